"""View sets around a model: cameras on an orbit, spread evenly over a sphere (Fibonacci
lattice) or over the upper hemisphere, each framing the whole model.

Framing fits the bounding sphere of ``bounds`` in both the vertical and the horizontal
field of view of an image of the given ``aspect`` (width / height), with a small margin,
so the model is whole at every aspect ratio. Azimuth is measured from +Z towards +X,
elevation up from the XZ plane (+Y is up), in degrees.

Every function raises :class:`~hsr.errors.CameraError` for bounds that are not a finite
(2, 3) box, a zero direction, an aspect that is not > 0, a fov outside (0, 180) degrees or
a number of views outside 1..1000000.
"""

from __future__ import annotations

import math
from typing import Any, cast

import numpy as np
from numpy.typing import ArrayLike

from ..choices import UpAxis
from ..errors import CameraError
from .camera import Camera

__all__ = ["DEFAULT_VIEW", "UP_AXES", "check_up_axis", "model_up", "up_vector",
           "default", "directions", "model_points", "framed", "orbit", "sphere", "hemisphere",
           "direction"]

DEFAULT_VIEW = (35.0, 25.0)  # azimuth, elevation in degrees: a three-quarter view
MARGIN = 1.05  # the sphere's silhouette fills at most 1 / 1.05 of the narrower side


# The world axis that points up: +Y (glTF, OpenGL, most meshes) or +Z (CAD, scans,
# Blender, STL). A Z-up model is seen as the same model turned to Y-up would be.
UP_AXES = ("y", "z")


def up_vector(up_axis: UpAxis = "y") -> np.ndarray:
    """The unit up vector of ``up_axis`` (``"y"`` or ``"z"``)."""
    return np.array([0.0, 1.0, 0.0] if check_up_axis(up_axis) == "y" else [0.0, 0.0, 1.0])


def check_up_axis(up_axis: object) -> UpAxis:
    """``up_axis`` checked: ``y`` or ``z`` (else :class:`~hsr.errors.CameraError`)."""
    if not isinstance(up_axis, str) or up_axis not in UP_AXES:
        raise CameraError(f"up_axis must be y or z, got {up_axis!r}")
    return cast(UpAxis, up_axis)


def model_up(model: Any, up_axis: str | None = None) -> UpAxis:
    """``up_axis`` checked, or when None the up axis ``model`` declares (a Scene's
    :meth:`~hsr.Scene.up_axis`, a Mesh's :attr:`~hsr.Mesh.up_axis`), else ``"y"``."""
    if up_axis is not None:
        return check_up_axis(up_axis)
    declared = getattr(model, "up_axis", None)
    declared = declared() if callable(declared) else declared
    return check_up_axis(declared) if declared in UP_AXES else "y"


def _oriented(vectors: np.ndarray, up_axis: str) -> np.ndarray:
    """Y-up ``vectors`` (..., 3) in the frame of ``up_axis``: for z, (x, y, z) ->
    (x, -z, y), the quarter turn about +X that takes +Y to +Z and the front (+Z) to -Y."""
    if check_up_axis(up_axis) == "y":
        return vectors
    out = np.empty_like(vectors)
    out[..., 0], out[..., 1], out[..., 2] = vectors[..., 0], -vectors[..., 2], vectors[..., 1]
    return out


def direction(azimuth: float, elevation: float, up_axis: UpAxis = "y") -> np.ndarray:
    """Unit vector from the model's centre towards the eye: ``azimuth`` degrees about the
    up axis (from the front, +Z for Y-up and -Y for Z-up, towards +X), ``elevation``
    degrees above the horizon."""
    az, el = math.radians(azimuth), math.radians(elevation)
    return _oriented(np.array([math.cos(el) * math.sin(az), math.sin(el),
                               math.cos(el) * math.cos(az)]), up_axis)


def framed(bounds: ArrayLike, toward: ArrayLike, aspect: float = 1.0,
           fov_y: float = 45.0, up_axis: UpAxis = "y") -> Camera:
    """A perspective camera on the line from the centre of ``bounds`` along ``toward`` (a
    direction to the eye) that sees the whole bounding sphere in an image of ``aspect``,
    with near and far hugging the sphere (:meth:`hsr.Camera.frame` with a 5% margin),
    ``up_axis`` up. Raises :class:`~hsr.errors.CameraError` as the module says."""
    return Camera.frame(bounds, toward, tuple(up_vector(up_axis)), fov_y, margin=MARGIN,
                        aspect=aspect)


def default(model: Any, aspect: float = 1.0, fov_y: float = 45.0,
            view: tuple = DEFAULT_VIEW, up_axis: UpAxis | None = None) -> Camera:
    """A model framed from ``view`` = (azimuth, elevation) in degrees, by default a
    three-quarter view from the front-right and above (35, 25: three faces of a box
    show, so the shape reads). ``model`` is a Mesh or Scene (the eye comes as close as
    its vertices allow with a 5% margin: the whole model, as large as it fits) or a
    (2, 3) box (as close as the box's corners allow). :func:`hsr.first_look` frames the
    same way from the view that shows the most of the model's shape, which is what
    ``hsr render MODEL`` draws. ``up_axis``: ``"y"`` or ``"z"`` (see :func:`direction`),
    None for the model's own (:func:`model_up`).
    Raises :class:`~hsr.errors.CameraError` as the module
    says, and for a view that is not two finite numbers."""
    try:
        if isinstance(view, str):
            raise TypeError
        azimuth, elevation = (float(v) for v in view)
    except (TypeError, ValueError):
        raise CameraError(f"view must be (azimuth, elevation) in degrees, got {view!r}") \
            from None
    if not (math.isfinite(azimuth) and math.isfinite(elevation)):
        raise CameraError(f"view must be finite degrees, got {view!r}")
    up = model_up(model, up_axis)
    if getattr(model, "kind", None) == "hsr-partitioned-scene":
        # A store on disk: framed by the box its metadata keeps (no part is read).
        points, bounds = None, model.bounds()
    else:
        points = model_points(model) if hasattr(model, "bounds") else None
        # The model's box from the same points (what Mesh/Scene.bounds() gives, without
        # transforming every face corner a second time).
        bounds = model if points is None else np.stack([points.min(axis=0),
                                                        points.max(axis=0)])
    return Camera.frame(bounds, direction(azimuth, elevation, up), tuple(up_vector(up)),
                        fov_y, margin=MARGIN, aspect=aspect,
                        fit="box" if points is None else "points", points=points)


def model_points(model: Any) -> np.ndarray:
    """(N, 3) world-space positions of the vertices that faces use, of a Mesh or of every
    instance of a Scene."""
    return model.world_points() if hasattr(model, "instances") else model.used_positions()


def directions(kind: str, n: int, elevation: float = 20.0, azimuth: float = 0.0,
               up_axis: UpAxis = "y") -> list:
    """The unit directions (centre towards eye) of a view set: ``orbit`` (``n`` equal
    azimuth steps from ``azimuth`` at ``elevation``), ``sphere`` or ``hemisphere``.
    :func:`orbit`, :func:`sphere` and :func:`hemisphere` frame a camera along each; a
    batch task frames only the views it renders. Raises
    :class:`~hsr.errors.CameraError` as the module says, and for an unknown kind."""
    n = _count(n)
    if kind == "orbit":
        return [direction(azimuth + 360.0 * k / n, elevation, up_axis) for k in range(n)]
    if kind in ("sphere", "hemisphere"):
        return list(_oriented(_fibonacci(n, -1.0 if kind == "sphere" else 0.0), up_axis))
    raise CameraError(f"view set must be orbit, sphere or hemisphere, got {kind!r}")


def orbit(bounds: ArrayLike, n: int, elevation: float = 20.0, aspect: float = 1.0,
          fov_y: float = 45.0, azimuth: float = 0.0, up_axis: UpAxis = "y") -> list:
    """``n`` cameras at equal azimuth steps (from the front towards +X, the first at
    ``azimuth``) at ``elevation`` about ``up_axis``. Raises
    :class:`~hsr.errors.CameraError` as the module says."""
    return [framed(bounds, d, aspect, fov_y, up_axis)
            for d in directions("orbit", n, elevation, azimuth, up_axis)]


def sphere(bounds: ArrayLike, n: int, aspect: float = 1.0, fov_y: float = 45.0,
           up_axis: UpAxis = "y") -> list:
    """``n`` cameras spread evenly over the whole sphere (Fibonacci lattice). Raises
    :class:`~hsr.errors.CameraError` as the module says."""
    return [framed(bounds, d, aspect, fov_y, up_axis)
            for d in directions("sphere", n, up_axis=up_axis)]


def hemisphere(bounds: ArrayLike, n: int, aspect: float = 1.0, fov_y: float = 45.0,
               up_axis: UpAxis = "y") -> list:
    """``n`` cameras spread evenly over the upper hemisphere (above the horizon of
    ``up_axis``). Raises :class:`~hsr.errors.CameraError` as the module says."""
    return [framed(bounds, d, aspect, fov_y, up_axis)
            for d in directions("hemisphere", n, up_axis=up_axis)]


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
