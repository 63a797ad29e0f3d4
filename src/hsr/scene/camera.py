"""Cameras with OpenGL's matrices: ``gluLookAt`` view, ``gluPerspective`` / ``glOrtho``
projection. Matrices act on column vectors (``p_clip = P @ V @ p_world``)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike

from ..errors import CameraError
from .mesh import MAX_COORDINATE

__all__ = ["Camera", "look_at_matrix", "perspective_matrix", "orthographic_matrix",
           "check_perspective_planes", "MAX_DEPTH_RATIO", "MAX_COORDINATE"]

# Window depth is stored as float32. For a perspective camera a surface at eye distance e
# has window depth 1 - near/e (far >> near); beyond e = near * 2**24 that is within half a
# float32 step of 1 and rounds to the far plane, where every surface ties and the depth
# test (LESS against a clear of 1) drops it. So far / near may be at most 2**24.
MAX_DEPTH_RATIO = float(1 << 24)
# Largest image side (hsr.geometry.viewport.MAX_SIZE, defined here so the camera files
# read in this package can refuse larger sizes): keeps snapped window coordinates well
# inside int64 edge arithmetic and buffers of a sane size.
MAX_IMAGE_SIDE = 32768
# Smallest field of view and orthographic height (relative to the camera's coordinates):
# below them one pixel is narrower than the float64 resolution of positions near the eye.
# OpenGL eye axes (x right, y up, looking down -z) -> OpenCV camera axes (y down, z ahead).
OPENGL_TO_OPENCV = np.diag([1.0, -1.0, -1.0])
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


def box_corners(bounds: np.ndarray) -> np.ndarray:
    """The (8, 3) corners of the (2, 3) box ``bounds``."""
    return np.array([[x, y, z] for x in bounds[:, 0] for y in bounds[:, 1]
                     for z in bounds[:, 2]])


def check_perspective_planes(near: float | None, far: float | None) -> None:
    """Raise :class:`CameraError` unless ``near`` and ``far`` are planes a perspective
    camera can render with: finite, 0 < near < far and far / near <= 2**24 (see
    :data:`MAX_DEPTH_RATIO`). For the planes given to cameras read from files, checked
    even when no file is read, so a bad value is never ignored unseen. A plane given as
    None (the file's, or fitted to the scene) is checked against the default of the
    other (0.1 near, 100 far) only for its sign."""
    if near is None or far is None:
        for value, what in ((near, "near"), (far, "far")):
            if value is not None and not _finite(value, what) > 0:
                raise CameraError(f"{what} must be > 0 for a perspective camera, got "
                                  f"{value}")
        return
    near, far = _finite(near, "near"), _finite(far, "far")
    if not near > 0:
        raise CameraError(f"near must be > 0 for a perspective camera, got {near}")
    if not far > near:
        raise CameraError(f"far ({far}) must be greater than near ({near})")
    if far / near > MAX_DEPTH_RATIO:
        raise CameraError(
            f"far / near = {far / near:.3g} is more than 2**24: float32 window depth "
            f"rounds every surface farther than near x 2**24 = {near * MAX_DEPTH_RATIO:.3g} "
            f"to the far plane; raise near or lower far")


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


def _matrix(value, shape, what) -> np.ndarray:
    try:
        m = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise CameraError(f"{what} must be a {shape[0]}x{shape[1]} array of numbers") from None
    if m.shape != shape or not np.isfinite(m).all() or np.abs(m).max() > MAX_COORDINATE:
        raise CameraError(f"{what} must be a finite {shape[0]}x{shape[1]} array, got shape "
                          f"{m.shape}")
    return m


def _points(value) -> np.ndarray:
    try:
        pts = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise CameraError("points must be an (N, 3) array of numbers") from None
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0 or not np.isfinite(pts).all() \
            or np.abs(pts).max() > MAX_COORDINATE:
        raise CameraError(f"points must be a finite (N, 3) array with N >= 1, got shape "
                          f"{pts.shape}")
    return pts


def _check_rotation(R: np.ndarray, what: str) -> None:
    if not np.allclose(R @ R.T, np.eye(3), atol=1e-6) or np.linalg.det(R) <= 0:
        raise CameraError(f"{what} must be a rotation (orthonormal, det +1)")


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
    if side_len <= 1e-12 * max(float(np.linalg.norm(up)), 1e-300):
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

    ``intrinsics`` (from :meth:`from_opencv` or :meth:`from_matrices`): a pinhole with its
    own focal lengths and principal point, as fractions of the image, ``(fx / W, fy / H,
    (cx + 0.5) / W, (cy + 0.5) / H)`` in OpenCV's pixels (centres on integers). It then
    sets the projection (an off-axis frustum, ``fov_y`` only describes it) and the camera
    sees the same field at any image size. For an orthographic camera (from a glOrtho
    matrix) the same four numbers hold image fractions per world unit and where the view
    axis meets the image (an off-centre box, ``ortho_height = 1 / b``).
    """

    eye: tuple
    target: tuple
    up: tuple
    fov_y: float = 45.0
    near: float = 0.1
    far: float = 100.0
    ortho_height: float | None = None
    intrinsics: tuple | None = None

    @classmethod
    def from_opencv(cls, K: ArrayLike, R: ArrayLike, t: ArrayLike, width: int, height: int,
                    near: float = 0.1, far: float = 100.0) -> Camera:
        """A camera from OpenCV's pinhole model: ``x_cam = R @ x_world + t`` with camera axes
        x right, y down, z forward, and ``K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]`` for an
        image of ``width`` x ``height`` pixels. OpenCV puts pixel *centres* on integer
        coordinates: a point projecting to (u, v) = (10.0, 20.0) is at the centre of hsr's
        pixel column 10, row 20 (hsr samples pixel (x, y) at (x + 0.5, y + 0.5)).

        Raises :class:`~hsr.errors.CameraError` for a K that is not upper triangular with
        positive focal lengths and zero skew, an R that is not a rotation (orthonormal,
        det +1), a t that is not three numbers, or what :meth:`validate` refuses.
        """
        K = _matrix(K, (3, 3), "K")
        R = _matrix(R, (3, 3), "R")
        t = _vec3(t, "t")
        for value, what in ((width, "width"), (height, "height")):
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
                raise CameraError(f"{what} must be a positive number of pixels, got {value!r}")
        fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
        if not (fx > 0 and fy > 0) or K[0, 1] != 0 or K[1, 0] != 0 \
                or not np.array_equal(K[2], [0.0, 0.0, 1.0]):
            raise CameraError(f"K must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0 "
                              f"(no skew), got {K.tolist()}")
        _check_rotation(R, "R")
        eye = -R.T @ t
        forward = R.T @ np.array([0.0, 0.0, 1.0])
        up = -(R.T @ np.array([0.0, 1.0, 0.0]))
        fov_y = math.degrees(2.0 * math.atan(height / (2.0 * fy)))
        cam = cls(tuple(eye), tuple(eye + forward), tuple(up), fov_y, _finite(near, "near"),
                  _finite(far, "far"),
                  intrinsics=(fx / width, fy / height, (cx + 0.5) / width, (cy + 0.5) / height))
        cam.validate()
        return cam

    def to_opencv(self, width: int, height: int) -> tuple:
        """``(K, R, t)`` of this camera for an image of ``width`` x ``height`` pixels, in
        OpenCV's conventions (see :meth:`from_opencv`). Raises
        :class:`~hsr.errors.CameraError` for an orthographic camera (OpenCV's model is a
        pinhole)."""
        if self.is_orthographic:
            raise CameraError("an orthographic camera has no OpenCV pinhole model")
        a, b, c, d = self._normalised_intrinsics(width / height)
        K = np.array([[a * width, 0.0, c * width - 0.5], [0.0, b * height, d * height - 0.5],
                      [0.0, 0.0, 1.0]])
        view = self.view_matrix
        return K, OPENGL_TO_OPENCV @ view[:3, :3], OPENGL_TO_OPENCV @ view[:3, 3]

    @classmethod
    def from_matrices(cls, view: ArrayLike, projection: ArrayLike) -> Camera:
        """A camera from OpenGL-convention 4x4 matrices: ``view`` (world -> eye, a rotation
        and a translation) and a ``projection``: a perspective frustum (glFrustum /
        gluPerspective form, possibly off-axis) or an orthographic box (glOrtho form,
        possibly off-centre). The projection is kept exactly: the camera sees the same
        field at any image size.

        Raises :class:`~hsr.errors.CameraError` for a view with scaling or shear, or a
        projection of neither form (or with near >= far, or what :meth:`validate` refuses).
        """
        view = _matrix(view, (4, 4), "view matrix")
        proj = _matrix(projection, (4, 4), "projection matrix")
        if not np.array_equal(view[3], [0.0, 0.0, 0.0, 1.0]):
            raise CameraError(f"view matrix must be affine, got last row {view[3].tolist()}")
        _check_rotation(view[:3, :3], "the view matrix's 3x3 part")
        rot = view[:3, :3]
        eye = -rot.T @ view[:3, 3]
        off_diagonal_zero = (proj[0, 1] == 0 and proj[1, 0] == 0
                             and np.array_equal(proj[2, :2], [0.0, 0.0])
                             and proj[0, 0] > 0 and proj[1, 1] > 0)
        frustum = (off_diagonal_zero and np.array_equal(proj[3], [0.0, 0.0, -1.0, 0.0])
                   and proj[0, 3] == 0 and proj[1, 3] == 0
                   and proj[2, 2] != 1 and proj[2, 2] != -1)
        box = (off_diagonal_zero and np.array_equal(proj[3], [0.0, 0.0, 0.0, 1.0])
               and proj[0, 2] == 0 and proj[1, 2] == 0 and proj[2, 2] < 0)
        if not (frustum or box):
            raise CameraError("projection must be a perspective frustum (glFrustum form: last "
                              "row 0, 0, -1, 0) or an orthographic box (glOrtho form: last "
                              "row 0, 0, 0, 1, near < far)")
        a, b = proj[0, 0] / 2.0, proj[1, 1] / 2.0
        if box:
            # glOrtho: z_ndc = P22 z_eye + P23 with P22 = -2 / (far - near) and
            # P23 = -(far + near) / (far - near).
            near = (proj[2, 3] + 1.0) / proj[2, 2]
            far = (proj[2, 3] - 1.0) / proj[2, 2]
            cam = cls(tuple(eye), tuple(eye - rot[2]), tuple(rot[1]), 45.0, float(near),
                      float(far), ortho_height=float(1.0 / b),
                      intrinsics=(a, b, (1.0 + proj[0, 3]) / 2.0, (1.0 - proj[1, 3]) / 2.0))
        else:
            near = proj[2, 3] / (proj[2, 2] - 1.0)
            far = proj[2, 3] / (proj[2, 2] + 1.0)
            fov_y = math.degrees(2.0 * math.atan(1.0 / (2.0 * b)))
            cam = cls(tuple(eye), tuple(eye - rot[2]), tuple(rot[1]), fov_y, float(near),
                      float(far), intrinsics=(a, b, (1.0 - proj[0, 2]) / 2.0,
                                              (1.0 + proj[1, 2]) / 2.0))
        cam.validate()
        return cam

    def _normalised_intrinsics(self, aspect: float) -> tuple:
        """(fx / W, fy / H, (cx + 0.5) / W, (cy + 0.5) / H) of the perspective projection."""
        if self.intrinsics is not None:
            return self.intrinsics
        f = 1.0 / math.tan(math.radians(self.fov_y) / 2.0)
        return f / (2.0 * aspect), f / 2.0, 0.5, 0.5

    @classmethod
    def look_at(cls, eye: ArrayLike, target: ArrayLike, up: ArrayLike = (0.0, 1.0, 0.0),
                fov_y: float = 45.0, near: float = 0.1, far: float = 100.0) -> Camera:
        """A perspective camera (gluLookAt + gluPerspective).

        Raises :class:`~hsr.errors.CameraError` as :meth:`validate` says.
        """
        cam = cls(tuple(_vec3(eye, "eye")), tuple(_vec3(target, "target")),
                  tuple(_vec3(up, "up")), _finite(fov_y, "fov"), _finite(near, "near"),
                  _finite(far, "far"))
        cam.validate()
        return cam

    @classmethod
    def orthographic(cls, eye: ArrayLike, target: ArrayLike, up: ArrayLike = (0.0, 1.0, 0.0),
                     height: float = 2.0, near: float = 0.1, far: float = 100.0) -> Camera:
        """An orthographic camera (gluLookAt + glOrtho) seeing ``height`` world units.

        Raises :class:`~hsr.errors.CameraError` as :meth:`validate` says.
        """
        cam = cls(tuple(_vec3(eye, "eye")), tuple(_vec3(target, "target")),
                  tuple(_vec3(up, "up")), 45.0, _finite(near, "near"), _finite(far, "far"),
                  _finite(height, "ortho height"))
        cam.validate()
        return cam

    @classmethod
    def frame(cls, bounds: ArrayLike, direction: ArrayLike = (0.0, 0.0, 1.0),
              up: ArrayLike = (0.0, 1.0, 0.0), fov_y: float = 45.0,
              ortho_height: float | None = None, margin: float = 1.1, aspect: float = 1.0,
              fit: str = "sphere", points: ArrayLike | None = None) -> Camera:
        """A camera that sees the whole box ``bounds`` ((2, 3): min, max) from ``direction``
        (pointing from the target towards the eye), with near/far hugging the box.

        ``fit="sphere"``: the box's bounding sphere fits in both the vertical and the
        horizontal field of view of an image of ``aspect`` (width / height), ``margin``
        times its radius (the same distance from every direction: what view sets want).
        ``fit="box"`` (perspective only): the eye comes as close as the box's eight corners
        allow, each inside both fields of view shrunk by ``margin`` (a tighter picture of
        the same whole model); ``fit="points"``: as close as the (N, 3) ``points`` allow
        (a model's vertices: as tight as the model itself, and still whole, since each
        triangle lies within its corners' projection). When
        ``direction`` is parallel to ``up`` (looking straight down or up), the image top
        points along -Z (looking down) or +Z (looking up) instead.

        Raises :class:`~hsr.errors.CameraError` for bounds that are not a finite box within
        +-1e100, a zero direction, an aspect or margin that is not a positive number, or a
        camera :meth:`validate` refuses.
        """
        try:
            bounds = np.asarray(bounds, dtype=np.float64)
        except (TypeError, ValueError):
            raise CameraError(f"cannot frame bounds {bounds!r}: they must be a finite (2, 3) "
                              f"box") from None
        if bounds.shape != (2, 3) or not np.isfinite(bounds).all() \
                or np.abs(bounds).max() > MAX_COORDINATE or (bounds[1] < bounds[0]).any():
            raise CameraError(f"cannot frame bounds {bounds.tolist()!r}: they must be a finite "
                              f"(2, 3) box (min, max) within +-{MAX_COORDINATE:g}")
        aspect, margin = _finite(aspect, "aspect"), _finite(margin, "margin")
        if not (aspect > 0 and margin > 0):
            raise CameraError(f"aspect and margin must be > 0, got {aspect!r}, {margin!r}")
        center = bounds.mean(axis=0)
        radius = max(float(np.linalg.norm(bounds[1] - bounds[0])) / 2.0, 1e-9)
        toward = _vec3(direction, "view direction")
        norm = np.linalg.norm(toward)
        if norm == 0:
            raise CameraError("view direction must not be zero")
        toward = toward / norm
        up = _vec3(up, "up")
        up_norm = np.linalg.norm(up)
        if up_norm > 0 and abs(toward @ up) > 0.999 * up_norm:
            up = np.array([0.0, 0.0, -math.copysign(1.0, toward @ up)])
        if ortho_height is not None:
            dist = 3.0 * radius
            eye = center + toward * dist
            return cls.orthographic(eye, center, up, ortho_height, dist - radius * 1.5,
                                    dist + radius * 1.5)
        half_y = math.radians(_finite(fov_y, "fov")) / 2.0
        if not 0 < half_y < math.pi / 2:
            raise CameraError(f"fov must be in (0, 180) degrees, got {fov_y}")
        half_x = math.atan(aspect * math.tan(half_y))
        if fit in ("box", "points"):
            if fit == "box":
                points = box_corners(bounds)
            else:
                points = _points(points)
            return cls._frame_points(points, center, radius, toward, up, fov_y,
                                     math.tan(half_x) / margin, math.tan(half_y) / margin)
        if fit != "sphere":
            raise CameraError(f"fit must be 'sphere', 'box' or 'points', got {fit!r}")
        dist = margin * radius / math.sin(min(half_x, half_y))
        eye = center + toward * dist
        near = max(dist - radius * 1.5, dist * 1e-3)
        return cls.look_at(eye, center, up, fov_y, near, dist + radius * 1.5)

    @classmethod
    def _frame_points(cls, points, center, radius, direction, up, fov_y, tan_x, tan_y):
        """The nearest eye on ``center + d * direction`` that sees every point within the
        half-angle tangents ``tan_x``, ``tan_y``: a point at offset ``o`` from the centre
        has lateral coordinates ``o . right``, ``o . up`` and depth ``d - o . direction``,
        so it is inside when ``d >= o . direction + |o . right| / tan_x`` (and likewise for
        up); ``d`` is the largest such bound. The view's rotation is gluLookAt's, the same
        at every distance."""
        rot = look_at_matrix(center + direction, center, up)[:3, :3]

        def nearest(center):
            offsets = points - center
            along = offsets @ direction
            lateral_x, lateral_y = offsets @ rot[0], offsets @ rot[1]
            # 5% of the radius in front of the nearest point at least: near stays > 0.
            dist = float(np.max(along + np.maximum(np.maximum(
                np.abs(lateral_x) / tan_x, np.abs(lateral_y) / tan_y), 0.05 * radius)))
            return dist, along, lateral_x / (dist - along), lateral_y / (dist - along)

        dist, along, slope_x, slope_y = nearest(center)
        # Then aim at the middle of what is seen (the box's centre is not the picture's):
        # move the target sideways by the middle of the slopes at the target's distance,
        # and fit again (any centre fits; this one leaves equal margins, nearly).
        center = center + dist * ((slope_x.max() + slope_x.min()) / 2 * rot[0]
                                  + (slope_y.max() + slope_y.min()) / 2 * rot[1])
        dist, along, _, _ = nearest(center)
        depth = dist - along
        near = max(0.95 * float(depth.min()), dist * 1e-3)
        far = 1.05 * float(depth.max())
        return cls.look_at(center + direction * dist, center, up, fov_y, near, far)

    def __repr__(self) -> str:
        def number(v) -> str:
            return f"{float(v):.6g}"

        def triple(v) -> str:
            return "(" + ", ".join(number(c) for c in v) + ")"

        lens = (f"ortho_height={number(self.ortho_height)}" if self.ortho_height is not None
                else f"fov_y={number(self.fov_y)}")
        extra = ("" if self.intrinsics is None
                 else f", intrinsics={triple(self.intrinsics)}")
        return (f"Camera(eye={triple(self.eye)}, target={triple(self.target)}, "
                f"up={triple(self.up)}, {lens}, near={number(self.near)}, "
                f"far={number(self.far)}{extra})")

    def pixel_rays(self, width: int, height: int) -> tuple:
        """``(origins, directions)``, each (H, W, 3) float64 in world space: the ray
        through the centre of every pixel (x + 0.5, y + 0.5; row 0 at the top) of a
        ``width`` x ``height`` image, from the near plane for an orthographic camera and
        from the eye for a perspective one, directions unit length (as Open3D's
        ``create_rays_pinhole``, in hsr's pixel convention). Feed them to
        :meth:`hsr.RayScene.cast` after ``reshape(-1, 3)``."""
        for side, what in ((width, "width"), (height, "height")):
            if isinstance(side, bool) or not isinstance(side, (int, np.integer)) \
                    or not 1 <= side <= MAX_IMAGE_SIDE:
                raise CameraError(f"pixel_rays: {what} must be a whole number in "
                                  f"1..{MAX_IMAGE_SIDE}, got {side!r}")
        x_ndc = 2.0 * (np.arange(width) + 0.5) / width - 1.0
        y_ndc = 1.0 - 2.0 * (np.arange(height) + 0.5) / height
        gx, gy = np.meshgrid(x_ndc, y_ndc)
        inverse = np.linalg.inv(self.projection_matrix(width / height) @ self.view_matrix)

        def unproject(z_ndc: float) -> np.ndarray:
            clip = np.stack([gx, gy, np.full_like(gx, z_ndc), np.ones_like(gx)], axis=-1)
            world = clip @ inverse.T
            return world[..., :3] / world[..., 3:]

        near, far = unproject(-1.0), unproject(1.0)
        directions = far - near
        directions /= np.linalg.norm(directions, axis=-1, keepdims=True)
        if self.is_orthographic:
            return near, directions
        return np.broadcast_to(np.asarray(self.eye, dtype=np.float64),
                               near.shape).copy(), directions

    def fitted(self, bounds: ArrayLike) -> Camera:
        """This camera with ``near`` and ``far`` enclosing the (2, 3) box ``bounds`` along
        its view axis (far 5% past the farthest corner, near 90% of the nearest one in
        front, at least far / 10^4): the planes ``--view`` framing gives, for a camera
        whose file names none. An orthographic camera is returned as it is."""
        import dataclasses

        if self.is_orthographic:
            return self
        corners = box_corners(np.asarray(bounds, dtype=np.float64))
        depth = -(corners @ self.view_matrix[2, :3] + self.view_matrix[2, 3])
        far = float(np.abs(depth).max()) * 1.05
        if not (math.isfinite(far) and far > 0):
            return self
        # The eye inside the box (or the box partly behind it): the nearest plane allowed.
        near = far * 1e-4 if depth.min() <= 0 else max(float(depth.min()) * 0.9, far * 1e-4)
        return dataclasses.replace(self, near=near, far=far)

    @property
    def is_orthographic(self) -> bool:
        return self.ortho_height is not None

    def validate(self) -> None:
        """Raise :class:`CameraError` unless the camera can be rendered exactly: finite
        values within +-1e100, near < far, for perspective 0 < near, fov in
        [1e-6, 180) degrees and far / near <= 2**24 (float32 window depth must tell the
        far plane from the near one), for orthographic a height of at least 1e-9 times
        the camera's coordinates; eye != target, up not parallel to the view."""
        for value, what in ((self.near, "near"), (self.far, "far")):
            _finite(value, what)
        if self.intrinsics is not None:
            values = np.asarray(self.intrinsics, dtype=np.float64)
            if values.shape != (4,) or not np.isfinite(values).all() or values[0] <= 0 \
                    or values[1] <= 0 or np.abs(values).max() > 1e12:
                raise CameraError(f"intrinsics must be four finite numbers with positive "
                                  f"focal lengths, got {self.intrinsics!r}")
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
            check_perspective_planes(self.near, self.far)
        self._view  # noqa: B018 - raises on eye == target or a bad up

    @cached_property
    def _view(self) -> np.ndarray:
        # Computed once per camera (the fields are frozen): a render asks several times,
        # and a batch renders thousands of small views where this was a fifth of the time.
        return look_at_matrix(self.eye, self.target, self.up)

    @property
    def view_matrix(self) -> np.ndarray:
        """(4, 4) world -> eye space (gluLookAt); a fresh copy each time."""
        return self._view.copy()

    def projection_matrix(self, aspect: float) -> np.ndarray:
        """(4, 4) eye -> clip space for an image of the given width / height."""
        if self.is_orthographic and self.intrinsics is None:
            half_h = float(self.ortho_height) / 2.0  # type: ignore[arg-type]
            half_w = half_h * aspect
            return orthographic_matrix(-half_w, half_w, -half_h, half_h, self.near, self.far)
        if self.is_orthographic:
            # A box kept from a glOrtho matrix: x_ndc = 2 a x_eye + 2 c - 1 and
            # y_ndc = 2 b y_eye + 1 - 2 d (c, d: the image fraction where the axis lands).
            a, b, c, d = self.intrinsics  # type: ignore[misc]
            proj = orthographic_matrix(-1.0, 1.0, -1.0, 1.0, self.near, self.far)
            proj[0, 0], proj[0, 3] = 2.0 * a, 2.0 * c - 1.0
            proj[1, 1], proj[1, 3] = 2.0 * b, 1.0 - 2.0 * d
            return proj
        if self.intrinsics is None:
            return perspective_matrix(self.fov_y, aspect, self.near, self.far)
        # An off-axis frustum from the normalised intrinsics: x_ndc = 2 (u + 0.5) / W - 1
        # with u = fx x / z + cx the OpenCV pixel of a point at depth z = -z_eye.
        a, b, c, d = self.intrinsics
        proj = perspective_matrix(90.0, 1.0, self.near, self.far)
        proj[0, 0], proj[0, 2] = 2.0 * a, 1.0 - 2.0 * c
        proj[1, 1], proj[1, 2] = 2.0 * b, 2.0 * d - 1.0
        return proj

    @property
    def forward(self) -> np.ndarray:
        """Unit viewing direction in world space."""
        d = np.asarray(self.target, dtype=np.float64) - np.asarray(self.eye, dtype=np.float64)
        return d / np.linalg.norm(d)
