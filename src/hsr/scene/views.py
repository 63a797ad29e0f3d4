"""View sets around a model: cameras on an orbit, spread evenly over a sphere (Fibonacci
lattice) or over the upper hemisphere, each framing the whole model.

Framing fits the bounding sphere of ``bounds`` in both the vertical and the horizontal
field of view of an image of the given ``aspect`` (width / height), with a small margin,
so the model is whole at every aspect ratio. Azimuth is measured from +Z towards +X,
elevation up from the XZ plane (+Y is up), in degrees.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import CameraError
from .camera import Camera

__all__ = ["framed", "orbit", "sphere", "hemisphere", "direction"]

_MARGIN = 1.05  # the sphere's silhouette fills at most 1 / 1.05 of the narrower side


def _sphere_of(bounds) -> tuple[np.ndarray, float]:
    try:
        b = np.asarray(bounds, dtype=np.float64)
    except (TypeError, ValueError):
        b = np.zeros(0)
    if b.shape != (2, 3) or not np.isfinite(b).all() or (b[1] < b[0]).any():
        raise CameraError(f"bounds must be a finite (2, 3) box (min, max), got {bounds!r}")
    return b.mean(axis=0), max(float(np.linalg.norm(b[1] - b[0])) / 2.0, 1e-9)


def direction(azimuth: float, elevation: float) -> np.ndarray:
    """Unit vector from the model's centre towards the eye."""
    az, el = math.radians(azimuth), math.radians(elevation)
    return np.array([math.cos(el) * math.sin(az), math.sin(el), math.cos(el) * math.cos(az)])


def framed(bounds, toward, aspect: float = 1.0, fov_y: float = 45.0) -> Camera:
    """A perspective camera on the line from the centre of ``bounds`` along ``toward`` (a
    direction to the eye) that sees the whole bounding sphere in an image of ``aspect``,
    with near and far hugging the sphere."""
    center, radius = _sphere_of(bounds)
    toward = np.asarray(toward, dtype=np.float64)
    norm = float(np.linalg.norm(toward))
    if not (np.isfinite(norm) and norm > 0):
        raise CameraError(f"view direction must be a non-zero vector, got {toward!r}")
    if not (math.isfinite(aspect) and aspect > 0):
        raise CameraError(f"aspect must be > 0, got {aspect!r}")
    toward = toward / norm
    half_y = math.radians(fov_y) / 2.0
    if not 0.0 < half_y < math.pi / 2:
        raise CameraError(f"fov must be in (0, 180) degrees, got {fov_y}")
    half_x = math.atan(aspect * math.tan(half_y))
    dist = _MARGIN * radius / math.sin(min(half_x, half_y))
    eye = center + toward * dist
    # Looking straight down or up, +Y cannot be "up": use -Z (the image top points away).
    up = (0.0, 1.0, 0.0) if abs(toward[1]) < 0.999 else (0.0, 0.0, -math.copysign(1.0,
                                                                                  toward[1]))
    return Camera.look_at(eye, center, up, fov_y, max(dist - 1.1 * radius, dist * 1e-3),
                          dist + 1.1 * radius)


def orbit(bounds, n: int, elevation: float = 20.0, aspect: float = 1.0,
          fov_y: float = 45.0, azimuth: float = 0.0) -> list:
    """``n`` cameras at equal azimuth steps (from +Z towards +X, the first at ``azimuth``)
    at ``elevation``."""
    n = _count(n)
    return [framed(bounds, direction(azimuth + 360.0 * k / n, elevation), aspect, fov_y)
            for k in range(n)]


def sphere(bounds, n: int, aspect: float = 1.0, fov_y: float = 45.0) -> list:
    """``n`` cameras spread evenly over the whole sphere (Fibonacci lattice)."""
    return [framed(bounds, d, aspect, fov_y) for d in _fibonacci(_count(n), -1.0)]


def hemisphere(bounds, n: int, aspect: float = 1.0, fov_y: float = 45.0) -> list:
    """``n`` cameras spread evenly over the upper hemisphere (y >= 0)."""
    return [framed(bounds, d, aspect, fov_y) for d in _fibonacci(_count(n), 0.0)]


def _count(n) -> int:
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 1 <= n <= 1_000_000:
        raise CameraError(f"the number of views must be an integer in 1..1000000, got {n!r}")
    return int(n)


def _fibonacci(n: int, y_min: float) -> np.ndarray:
    """(n, 3) unit vectors with y evenly spaced in (y_min, 1) and longitudes stepped by
    the golden angle: equal-area cells on the sphere (or the cap above y_min)."""
    k = np.arange(n) + 0.5
    y = 1.0 - (1.0 - y_min) * k / n
    r = np.sqrt(np.maximum(0.0, 1.0 - y * y))
    phi = k * math.pi * (3.0 - math.sqrt(5.0))
    return np.stack([r * np.sin(phi), y, r * np.cos(phi)], axis=1)
