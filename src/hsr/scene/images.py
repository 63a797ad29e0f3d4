"""Images that scenes carry: diffuse textures read from files (Pillow) or arrays, and
procedural ones. Row 0 of a loaded texture is ``v`` near 0 (OBJ/OpenGL: the image's
bottom row), so rows are flipped on load."""

from __future__ import annotations

import io
import os
import struct

import numpy as np

from ..errors import MeshError
from .files import read_regular

__all__ = ["load_texture", "checkerboard", "image_size_ok", "MAX_TEXTURE_PIXELS"]

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
    from PIL import Image

    data = read_regular(path, "texture file", MAX_TEXTURE_BYTES)
    problem = image_size_ok(data, MAX_TEXTURE_PIXELS)
    if problem:
        raise MeshError(f"{path}: {problem}")
    try:
        with Image.open(io.BytesIO(data)) as img:
            return np.asarray(img.convert("RGB"))
    except (OSError, ValueError, SyntaxError) as exc:
        raise MeshError(f"{path}: not a readable image ({exc})") from None


def image_size_ok(blob: bytes, max_pixels: int) -> str | None:
    """None when ``blob`` is an image Pillow reads whose header claims at most
    ``max_pixels``; else what is wrong with it (the header alone is read, so a
    decompression bomb costs nothing)."""
    import warnings

    from PIL import Image, UnidentifiedImageError

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", Image.DecompressionBombWarning)
            with Image.open(io.BytesIO(blob)) as img:
                width, height = img.size
    except (Image.DecompressionBombError, Image.DecompressionBombWarning):
        return f"the image claims more pixels than hsr reads ({max_pixels:,})"
    except UnidentifiedImageError:
        return "not an image Pillow can identify"
    except (OSError, ValueError, SyntaxError, struct.error) as exc:
        return f"not a readable image ({type(exc).__name__}: {exc})"
    if width * height > max_pixels:
        return (f"the image is {width}x{height} pixels, more than the {max_pixels:,} hsr "
                f"reads")
    return None


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
