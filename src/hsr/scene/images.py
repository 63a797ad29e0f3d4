"""Images that scenes carry: diffuse textures read from files (Pillow) or arrays, and
procedural ones. Row 0 of a loaded texture is ``v`` near 0 (OBJ/OpenGL: the image's
bottom row), so rows are flipped on load."""

from __future__ import annotations

import os

import numpy as np

from ..errors import MeshError
from .files import read_regular

__all__ = ["load_texture", "checkerboard", "MAX_TEXTURE_PIXELS"]

# Largest texture read from a file (8192 x 8192): an image header may claim any size, and
# decoding 60000 x 60000 pixels would take 10 GB.
MAX_TEXTURE_PIXELS = 8192 * 8192
MAX_TEXTURE_BYTES = 512 << 20


def load_texture(source) -> np.ndarray:
    """(H, W, 3) uint8 texture with row 0 = ``v`` near 0 (the image's bottom row), from a
    path (TGA, PNG, JPG, ... via Pillow) or an (H, W, 3|4) / (H, W) array given with row 0
    at the top, like an image file."""
    if isinstance(source, (str, os.PathLike)):
        pixels = _read_image(os.fspath(source))
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


def _read_image(path: str) -> np.ndarray:
    """(H, W, 3) uint8 pixels of an image file (row 0 = top), refusing files that are not
    regular, too large, or whose header claims more than :data:`MAX_TEXTURE_PIXELS`."""
    import io
    import warnings

    from PIL import Image, UnidentifiedImageError

    data = read_regular(path, "texture file", MAX_TEXTURE_BYTES)
    try:
        with warnings.catch_warnings():
            # Pillow warns (then refuses) on decompression bombs; hsr refuses before that.
            warnings.simplefilter("error", Image.DecompressionBombWarning)
            with Image.open(io.BytesIO(data)) as img:
                width, height = img.size
                if width * height > MAX_TEXTURE_PIXELS:
                    raise MeshError(f"{path}: texture is {width}x{height} pixels, more than "
                                    f"the {MAX_TEXTURE_PIXELS:,} hsr reads")
                pixels = np.asarray(img.convert("RGB"))
    except (Image.DecompressionBombError, Image.DecompressionBombWarning):
        raise MeshError(f"{path}: the image claims more pixels than hsr reads "
                        f"({MAX_TEXTURE_PIXELS:,})") from None
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError) as exc:
        raise MeshError(f"{path}: not a readable image ({exc})") from None
    return pixels


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
