"""Images that scenes carry: diffuse textures read from files (Pillow) or arrays, and
procedural ones. Row 0 of a loaded texture is ``v`` near 0 (OBJ/OpenGL: the image's
bottom row), so rows are flipped on load."""

from __future__ import annotations

import os

import numpy as np

from ..errors import MeshError

__all__ = ["load_texture", "checkerboard"]


def load_texture(source) -> np.ndarray:
    """(H, W, 3) uint8 texture with row 0 = ``v`` near 0 (the image's bottom row), from a
    path (TGA, PNG, JPG, ... via Pillow) or an (H, W, 3|4) / (H, W) array given with row 0
    at the top, like an image file."""
    if isinstance(source, (str, os.PathLike)):
        path = os.fspath(source)
        if not os.path.exists(path):
            raise MeshError(f"texture file not found: {path}")
        from PIL import Image, UnidentifiedImageError

        try:
            with Image.open(path) as img:
                pixels = np.asarray(img.convert("RGB"))
        except (UnidentifiedImageError, OSError, ValueError) as exc:
            raise MeshError(f"{path}: not a readable image ({exc})") from None
    else:
        pixels = np.asarray(source)
        if pixels.ndim == 2:
            pixels = np.repeat(pixels[:, :, None], 3, axis=2)
        if pixels.ndim != 3 or pixels.shape[2] not in (3, 4) or pixels.shape[0] == 0 \
                or pixels.shape[1] == 0:
            raise MeshError(f"a texture array must have shape (H, W, 3) or (H, W, 4), "
                            f"got {pixels.shape}")
        if pixels.dtype != np.uint8:
            if not np.isfinite(pixels).all():
                raise MeshError("texture array has NaN or infinite values")
            pixels = np.clip(pixels, 0, 255).astype(np.uint8)
        pixels = pixels[:, :, :3]
    return np.ascontiguousarray(pixels[::-1])


def checkerboard(squares: int = 8, texels_per_square: int = 8,
                 colors=((235, 235, 235), (40, 40, 40))) -> np.ndarray:
    """(H, W, 3) uint8 checkerboard image (row 0 = top), ``squares`` x ``squares``."""
    n = squares * texels_per_square
    idx = np.arange(n) // texels_per_square
    odd = (idx[:, None] + idx[None, :]) % 2 == 1
    image = np.empty((n, n, 3), dtype=np.uint8)
    image[~odd] = colors[0]
    image[odd] = colors[1]
    return image
