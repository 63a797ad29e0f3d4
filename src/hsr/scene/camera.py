"""Cameras with OpenGL's matrices: ``gluLookAt`` view, ``gluPerspective`` / ``glOrtho``
projection. Matrices act on column vectors (``p_clip = P @ V @ p_world``)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import CameraError

__all__ = ["Camera", "look_at_matrix", "perspective_matrix", "orthographic_matrix",
           "MAX_DEPTH_RATIO", "MAX_COORDINATE"]

# Window depth is stored as float32. For a perspective camera a surface at eye distance e
# has window depth 1 - near/e (far >> near); beyond e = near * 2**24 that is within half a
# float32 step of 1 and rounds to the far plane, where every surface ties and the depth
# test (LESS against a clear of 1) drops it. So far / near may be at most 2**24.
MAX_DEPTH_RATIO = float(1 << 24)
# Coordinates (and products of two of them) must stay finite in float64.
MAX_COORDINATE = 1e100
# Smallest field of view and orthographic height (relative to the camera's coordinates):
# below them one pixel is narrower than the float64 resolution of positions near the eye.
MIN_FOV_DEGREES = 1e-6
MIN_ORTHO_RELATIVE = 1e-9


def _vec3(value, what) -> np.ndarray:
    try:
        v = np.asarray(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise CameraError(f"{what} must be three numbers, got {value!r}") from None
    if v.shape != (3,):
        raise CameraError(f"{what} must be three numbers, got {value!r}")
    if not np.isfinite(v).all():
        raise CameraError(f"{what} must be finite, got {v.tolist()}")
    if np.abs(v).max() > MAX_COORDINATE:
        raise CameraError(f"{what} coordinates must be within +-{MAX_COORDINATE:g}, "
                          f"got {v.tolist()}")
    return v


def _finite(value, what) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise CameraError(f"{what} must be a number, got {value!r}") from None
    if not math.isfinite(v):
        raise CameraError(f"{what} must be finite, got {value!r}")
    if abs(v) > MAX_COORDINATE:
        raise CameraError(f"{what} must be within +-{MAX_COORDINATE:g}, got {value!r}")
    return v


def look_at_matrix(eye, target, up) -> np.ndarray:
    """gluLookAt: world -> eye space; the camera looks down -Z with +Y up."""
    eye, target, up = _vec3(eye, "eye"), _vec3(target, "target"), _vec3(up, "up")
    forward = target - eye
    dist = np.linalg.norm(forward)
    if dist == 0:
        raise CameraError("eye and target are the same point")
    forward /= dist
    side = np.cross(forward, up)
    side_len = np.linalg.norm(side)
    if side_len <= 1e-12 * max(np.linalg.norm(up), 1e-300):
        raise CameraError("up vector is zero or parallel to the viewing direction")
    side /= side_len
    true_up = np.cross(side, forward)
    view = np.eye(4)
    view[0, :3], view[1, :3], view[2, :3] = side, true_up, -forward
    view[:3, 3] = -view[:3, :3] @ eye
    return view


def perspective_matrix(fov_y: float, aspect: float, near: float, far: float) -> np.ndarray:
    """gluPerspective: ``fov_y`` in degrees; eye space -> clip space (``w = -z_eye``)."""
    f = 1.0 / math.tan(math.radians(fov_y) / 2.0)
    proj = np.zeros((4, 4))
    proj[0, 0] = f / aspect
    proj[1, 1] = f
    proj[2, 2] = (far + near) / (near - far)
    proj[2, 3] = 2.0 * far * near / (near - far)
    proj[3, 2] = -1.0
    return proj


def orthographic_matrix(left, right, bottom, top, near, far) -> np.ndarray:
    """glOrtho: eye space -> clip space (``w = 1``)."""
    proj = np.eye(4)
    proj[0, 0] = 2.0 / (right - left)
    proj[1, 1] = 2.0 / (top - bottom)
    proj[2, 2] = -2.0 / (far - near)
    proj[0, 3] = -(right + left) / (right - left)
    proj[1, 3] = -(top + bottom) / (top - bottom)
    proj[2, 3] = -(far + near) / (far - near)
    return proj


@dataclass(frozen=True)
class Camera:
    """A pinhole (perspective) or orthographic camera.

    ``view_matrix`` maps world to eye space; ``projection_matrix(aspect)`` maps eye to clip
    space, the aspect (width / height) coming from the image at render time.
    Perspective: ``fov_y`` degrees in (0, 180), ``0 < near < far``. Orthographic:
    ``ortho_height`` world units visible vertically, ``near < far`` (either may be negative).
    """

    eye: tuple
    target: tuple
    up: tuple
    fov_y: float = 45.0
    near: float = 0.1
    far: float = 100.0
    ortho_height: float | None = None

    @classmethod
    def look_at(cls, eye, target, up=(0.0, 1.0, 0.0), fov_y=45.0, near=0.1, far=100.0):
        """A perspective camera (gluLookAt + gluPerspective).

        Raises :class:`~hsr.errors.CameraError` as :meth:`validate` says.
        """
        cam = cls(tuple(_vec3(eye, "eye")), tuple(_vec3(target, "target")),
                  tuple(_vec3(up, "up")), _finite(fov_y, "fov"), _finite(near, "near"),
                  _finite(far, "far"))
        cam.validate()
        return cam

    @classmethod
    def orthographic(cls, eye, target, up=(0.0, 1.0, 0.0), height=2.0, near=0.1, far=100.0):
        """An orthographic camera (gluLookAt + glOrtho) seeing ``height`` world units.

        Raises :class:`~hsr.errors.CameraError` as :meth:`validate` says.
        """
        cam = cls(tuple(_vec3(eye, "eye")), tuple(_vec3(target, "target")),
                  tuple(_vec3(up, "up")), 45.0, _finite(near, "near"), _finite(far, "far"),
                  _finite(height, "ortho height"))
        cam.validate()
        return cam

    @classmethod
    def frame(cls, bounds, direction=(0.0, 0.0, 1.0), up=(0.0, 1.0, 0.0), fov_y=45.0,
              ortho_height=None, margin=1.1):
        """A camera that sees the whole box ``bounds`` ((2, 3): min, max) from ``direction``
        (pointing from the target towards the eye), with near/far hugging the box.

        Raises :class:`~hsr.errors.CameraError` for bounds that are not a finite box within
        +-1e100, a zero direction, or a camera :meth:`validate` refuses.
        """
        try:
            bounds = np.asarray(bounds, dtype=np.float64)
        except (TypeError, ValueError):
            raise CameraError(f"cannot frame bounds {bounds!r}: they must be a finite (2, 3) "
                              f"box") from None
        if bounds.shape != (2, 3) or not np.isfinite(bounds).all() \
                or np.abs(bounds).max() > MAX_COORDINATE:
            raise CameraError(f"cannot frame bounds {bounds.tolist()!r}: they must be a finite "
                              f"(2, 3) box within +-{MAX_COORDINATE:g}")
        center = bounds.mean(axis=0)
        radius = max(float(np.linalg.norm(bounds[1] - bounds[0])) / 2.0, 1e-9)
        direction = _vec3(direction, "view direction")
        norm = np.linalg.norm(direction)
        if norm == 0:
            raise CameraError("view direction must not be zero")
        direction = direction / norm
        if ortho_height is not None:
            dist = 3.0 * radius
            eye = center + direction * dist
            return cls.orthographic(eye, center, up, ortho_height, dist - radius * 1.5,
                                    dist + radius * 1.5)
        half = math.radians(_finite(fov_y, "fov")) / 2.0
        if not 0 < half < math.pi / 2:
            raise CameraError(f"fov must be in (0, 180) degrees, got {fov_y}")
        dist = margin * radius / math.sin(half)
        eye = center + direction * dist
        near = max(dist - radius * 1.5, dist * 1e-3)
        return cls.look_at(eye, center, up, fov_y, near, dist + radius * 1.5)

    @property
    def is_orthographic(self) -> bool:
        return self.ortho_height is not None

    def validate(self):
        """Raise :class:`CameraError` unless the camera can be rendered exactly: finite
        values within +-1e100, near < far, for perspective 0 < near, fov in
        [1e-6, 180) degrees and far / near <= 2**24 (float32 window depth must tell the
        far plane from the near one), for orthographic a height of at least 1e-9 times
        the camera's coordinates; eye != target, up not parallel to the view."""
        for value, what in ((self.near, "near"), (self.far, "far")):
            _finite(value, what)
        if self.is_orthographic:
            height = _finite(self.ortho_height, "ortho height")
            if not height > 0:
                raise CameraError(f"ortho height must be > 0, got {self.ortho_height}")
            scale = max(1.0, float(np.abs(np.concatenate([self.eye, self.target])).max()),
                        abs(self.near), abs(self.far))
            if height < MIN_ORTHO_RELATIVE * scale:
                raise CameraError(
                    f"ortho height {height:g} is below {MIN_ORTHO_RELATIVE:g} x the camera's "
                    f"coordinates ({scale:g}): a pixel would be finer than float64 can place "
                    f"points there")
            if not self.far > self.near:
                raise CameraError(f"far ({self.far}) must be greater than near ({self.near})")
        else:
            fov = _finite(self.fov_y, "fov")
            if not MIN_FOV_DEGREES <= fov < 180:
                raise CameraError(f"fov must be in [{MIN_FOV_DEGREES:g}, 180) degrees, "
                                  f"got {self.fov_y}")
            if not self.near > 0:
                raise CameraError(f"near must be > 0 for a perspective camera, got {self.near}")
            if not self.far > self.near:
                raise CameraError(f"far ({self.far}) must be greater than near ({self.near})")
            if self.far / self.near > MAX_DEPTH_RATIO:
                raise CameraError(
                    f"far / near = {self.far / self.near:.3g} is more than 2**24: float32 "
                    f"window depth rounds every surface farther than near x 2**24 = "
                    f"{self.near * MAX_DEPTH_RATIO:.3g} to the far plane; raise near or "
                    f"lower far")
        look_at_matrix(self.eye, self.target, self.up)  # raises on eye == target, bad up

    @property
    def view_matrix(self) -> np.ndarray:
        """(4, 4) world -> eye space (gluLookAt)."""
        return look_at_matrix(self.eye, self.target, self.up)

    def projection_matrix(self, aspect: float) -> np.ndarray:
        """(4, 4) eye -> clip space for an image of the given width / height."""
        if self.is_orthographic:
            half_h = self.ortho_height / 2.0
            half_w = half_h * aspect
            return orthographic_matrix(-half_w, half_w, -half_h, half_h, self.near, self.far)
        return perspective_matrix(self.fov_y, aspect, self.near, self.far)

    @property
    def forward(self) -> np.ndarray:
        """Unit viewing direction in world space."""
        d = np.asarray(self.target, dtype=np.float64) - np.asarray(self.eye, dtype=np.float64)
        return d / np.linalg.norm(d)
