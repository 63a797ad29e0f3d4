"""Diffuse textures: sampling at perspective-correct uv (images are read by
:mod:`hsr.scene.images`).

Conventions follow OpenGL with OBJ texture coordinates: ``v = 0`` is the *bottom* row of
the image (Pillow's row 0 is the top, so rows are flipped on load), texel ``(i, j)``
covers ``[i, i + 1) x [j, j + 1)`` in ``(u * width, v * height)``, its centre is at
``+0.5``. Filters: ``nearest`` (GL_NEAREST: the texel containing the point) and
``bilinear`` (GL_LINEAR: the four texels around ``(u * width - 0.5, v * height - 0.5)``).
Wrap modes: ``repeat`` (GL_REPEAT) and ``clamp`` (GL_CLAMP_TO_EDGE).
"""

from __future__ import annotations

import numpy as np

from ..errors import check_choice

__all__ = ["FILTERS", "WRAPS", "sample"]

FILTERS = ("nearest", "bilinear")
WRAPS = ("repeat", "clamp")


def _wrap(index, size, wrap):
    if wrap == "repeat":
        return np.mod(index, size)
    return np.clip(index, 0, size - 1)


# Beyond this a coordinate times a texture side may not fit the int64 texel index.
_FAR_UV = 2.0 ** 20


def _reduced(uv: np.ndarray, wrap: str) -> np.ndarray:
    """``uv`` with coordinates far outside [0, 1] brought back: GL_REPEAT uses only their
    fractional part and GL_CLAMP_TO_EDGE only their side, so no texel changes, and
    ordinary coordinates are left exactly as they are."""
    far = np.abs(uv) > _FAR_UV
    if not far.any():
        return uv
    uv = uv.copy()
    uv[far] = (uv[far] - np.floor(uv[far]) if wrap == "repeat"
               else np.clip(uv[far], -1.0, 2.0))
    return uv


def sample(texture: np.ndarray, uv: np.ndarray, filter: str = "bilinear",
           wrap: str = "repeat") -> np.ndarray:
    """(K, 3) float64 colours (0..255) of ``texture`` (from
    :func:`hsr.scene.images.load_texture`) at
    (K, 2) texture coordinates ``uv``."""
    check_choice(filter, FILTERS, "texture filter")
    check_choice(wrap, WRAPS, "texture wrap")
    height, width = texture.shape[:2]
    uv = _reduced(uv, wrap)
    s = uv[:, 0] * width
    t = uv[:, 1] * height
    if filter == "nearest":
        i = _wrap(np.floor(s).astype(np.int64), width, wrap)
        j = _wrap(np.floor(t).astype(np.int64), height, wrap)
        return texture[j, i].astype(np.float64)
    s = s - 0.5
    t = t - 0.5
    i0 = np.floor(s)
    j0 = np.floor(t)
    a = (s - i0)[:, None]
    b = (t - j0)[:, None]
    i0 = i0.astype(np.int64)
    j0 = j0.astype(np.int64)
    i1, j1 = _wrap(i0 + 1, width, wrap), _wrap(j0 + 1, height, wrap)
    i0, j0 = _wrap(i0, width, wrap), _wrap(j0, height, wrap)
    tex = texture.astype(np.float64) if texture.dtype != np.float64 else texture
    return ((1 - a) * (1 - b) * tex[j0, i0] + a * (1 - b) * tex[j0, i1]
            + (1 - a) * b * tex[j1, i0] + a * b * tex[j1, i1])
