"""Cameras from the files other tools write: NeRF / instant-ngp / Blender ``transforms.json``
(read and write) and COLMAP text models (``cameras.txt`` + ``images.txt``).

Half pixels: OpenCV puts the centre of the top-left pixel at (0, 0); COLMAP, and the NeRF
files made from it, at (0.5, 0.5), which is hsr's own continuous image coordinate (hsr
samples pixel (x, y) at (x + 0.5, y + 0.5)). So a COLMAP or NeRF principal point ``cx``
is OpenCV's ``cx - 0.5``; each reader and writer converts (tests pin each convention with
a point that projects exactly onto a pixel centre).
"""

from __future__ import annotations

import json
import math
import os

import numpy as np
from numpy.typing import ArrayLike

from ..errors import CameraError
from .camera import MAX_IMAGE_SIDE, OPENGL_TO_OPENCV, Camera
from .files import MAX_MTL_BYTES, read_regular

__all__ = ["read_transforms", "write_transforms", "read_colmap", "COLMAP_MODELS"]

# COLMAP camera models hsr renders exactly (pinholes without distortion).
COLMAP_MODELS = ("SIMPLE_PINHOLE", "PINHOLE")


def _read_text(path, what) -> str:
    try:
        return read_regular(path, what, MAX_MTL_BYTES, CameraError).decode("utf-8")
    except UnicodeDecodeError:
        raise CameraError(f"{path}: not UTF-8 text") from None


def _number(value, what, where) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) \
            or not math.isfinite(value):
        raise CameraError(f"{where}: {what} must be a finite number, got {value!r}")
    return float(value)


def _pixels(value, what, where) -> int:
    """An image side: a whole number (an integral float is taken) in 1..MAX_SIZE."""
    if isinstance(value, str):
        try:
            value = float(value)
        except ValueError:
            pass
    if (isinstance(value, bool) or not isinstance(value, (int, float))
            or not math.isfinite(value) or value != int(value)
            or not 1 <= value <= MAX_IMAGE_SIDE):
        raise CameraError(f"{where}: {what} must be a whole number of pixels in "
                          f"1..{MAX_IMAGE_SIDE}, got {value!r}")
    return int(value)


def _positive(value, what, where) -> float:
    value = _number(value, what, where)
    if not value > 0:
        raise CameraError(f"{where}: {what} must be > 0, got {value!r}")
    return value


def _angle(value, what, where) -> float:
    """A field of view in radians, in (0, pi)."""
    value = _number(value, what, where)
    if not 0.0 < value < math.pi:
        raise CameraError(f"{where}: {what} must be in (0, pi) radians, got {value!r}")
    return value


# The planes of a camera file's camera when neither the call, the file nor a scene to fit
# them to gives any.
DEFAULT_PLANES = (0.1, 100.0)


def _planes(keys: dict, near, far, where: str) -> tuple:
    """``(near, far, fit)``: the planes given to the call, else the file's ``near`` /
    ``far``, else :data:`DEFAULT_PLANES` with ``fit`` True (fit them to the scene when
    one is known)."""
    fit = near is None and far is None and "near" not in keys and "far" not in keys
    if near is None:
        near = _positive(keys["near"], "near", where) if "near" in keys else DEFAULT_PLANES[0]
    if far is None:
        far = _positive(keys["far"], "far", where) if "far" in keys else DEFAULT_PLANES[1]
    return near, far, fit


def read_transforms(path: str | os.PathLike, near: float | None = None,
                    far: float | None = None, bounds: ArrayLike | None = None) -> tuple:
    """Cameras of a NeRF-style ``transforms.json``: ``(cameras, file_paths, (w, h))``.

    Planes: ``near`` / ``far`` when given, else the file's ``near`` / ``far`` (top level
    or per frame, as :func:`write_transforms` writes them), else fitted to the (2, 3) box
    ``bounds`` of the scene (:meth:`hsr.Camera.fitted`), else 0.1 and 100.

    Intrinsics from ``fl_x``/``fl_y``/``cx``/``cy`` (COLMAP's half-pixel convention) or
    ``camera_angle_x`` (and ``camera_angle_y``; principal point at the centre), with
    ``w``/``h``; a frame may override any of them. Each frame's ``transform_matrix`` is
    camera-to-world in OpenGL axes (the camera looks down -Z, +Y up). Raises
    :class:`~hsr.errors.CameraError` naming the frame and key on anything missing or
    malformed."""
    cameras, names, size, fit = transforms_cameras(path, near, far)
    return fitted_where(cameras, fit, bounds), names, size


def fitted_where(cameras: list, fit: list, bounds) -> list:
    """``cameras`` with those marked in ``fit`` fitted to the box ``bounds`` (as they are
    when ``bounds`` is None)."""
    if bounds is None:
        return list(cameras)
    return [cam.fitted(bounds) if f else cam for cam, f in zip(cameras, fit)]


def transforms_cameras(path, near: float | None = None, far: float | None = None) -> tuple:
    """:func:`read_transforms` before any fitting: ``(cameras, file_paths, (w, h), fit)``,
    ``fit[k]`` True where camera k's planes came from neither the call nor the file."""
    path = os.fspath(path)
    try:
        doc = json.loads(_read_text(path, "camera file"))
    except json.JSONDecodeError as exc:
        raise CameraError(f"{path}: not JSON ({exc.msg} at line {exc.lineno})") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("frames"), list) \
            or not doc["frames"]:
        raise CameraError(f"{path}: a transforms.json needs a non-empty 'frames' list")
    cameras, names, size, fits = [], [], None, []
    for k, frame in enumerate(doc["frames"]):
        where = f"{path}: frame {k}"
        if not isinstance(frame, dict):
            raise CameraError(f"{where}: not an object")
        keys = {**doc, **frame}
        if "w" not in keys or "h" not in keys:
            raise CameraError(f"{where}: needs integer 'w' and 'h'")
        w, h = _pixels(keys["w"], "w", where), _pixels(keys["h"], "h", where)
        if "fl_x" in keys:
            fx = _positive(keys["fl_x"], "fl_x", where)
            fy = _positive(keys.get("fl_y", fx), "fl_y", where)
        elif "camera_angle_x" in keys:
            fx = 0.5 * w / math.tan(_angle(keys["camera_angle_x"], "camera_angle_x", where) / 2)
            fy = (0.5 * h / math.tan(_angle(keys["camera_angle_y"], "camera_angle_y", where) / 2)
                  if "camera_angle_y" in keys else fx)
        else:
            raise CameraError(f"{where}: needs 'fl_x' or 'camera_angle_x'")
        cx = _number(keys.get("cx", w / 2.0), "cx", where)
        cy = _number(keys.get("cy", h / 2.0), "cy", where)
        try:
            c2w = np.asarray(frame["transform_matrix"], dtype=np.float64)
        except (KeyError, TypeError, ValueError):
            raise CameraError(f"{where}: needs a 4x4 'transform_matrix'") from None
        if c2w.shape != (4, 4) or not np.isfinite(c2w).all():
            raise CameraError(f"{where}: transform_matrix must be a finite 4x4 matrix")
        rot = c2w[:3, :3]
        if not np.allclose(rot.T @ rot, np.eye(3), atol=1e-6) or np.linalg.det(rot) <= 0:
            raise CameraError(f"{where}: transform_matrix must be a rotation and a "
                              f"translation (no scale)")
        R = OPENGL_TO_OPENCV @ rot.T
        t = -R @ c2w[:3, 3]
        K = np.array([[fx, 0.0, cx - 0.5], [0.0, fy, cy - 0.5], [0.0, 0.0, 1.0]])
        near_k, far_k, fit = _planes(keys, near, far, where)
        try:
            cam = Camera.from_opencv(K, R, t, w, h, near=near_k, far=far_k)
        except CameraError as exc:
            raise CameraError(f"{where}: {exc}") from None
        cameras.append(cam)
        fits.append(fit)
        names.append(str(frame.get("file_path", f"{k:04d}")))
        size = size or (w, h)
    return cameras, names, size, fits


def write_transforms(path: str | os.PathLike, cameras: list, width: int, height: int,
                     file_paths: list | None = None) -> None:
    """Write ``cameras`` (perspective) as a NeRF-style ``transforms.json`` for images of
    ``width`` x ``height``: intrinsics (``fl_x``, ``fl_y``, ``cx``, ``cy`` in COLMAP's
    half-pixel convention, ``w``, ``h``) and the planes (``near``, ``far``, which
    :func:`read_transforms` reads back) at the top when all cameras share them, else per
    frame; ``transform_matrix`` camera-to-world in OpenGL axes. Raises
    :class:`~hsr.errors.CameraError` for an orthographic camera and
    :class:`~hsr.errors.OutputError` when the file cannot be written."""
    from ..errors import OutputError
    from .files import check_output

    path = check_output(path, (".json",))
    cameras = list(cameras)
    if not cameras:
        raise CameraError("write_transforms needs at least one camera")
    names = list(file_paths) if file_paths is not None else [f"{k:04d}" for k in
                                                            range(len(cameras))]
    if len(names) != len(cameras):
        raise CameraError(f"{len(names)} file paths for {len(cameras)} cameras")
    frames, intrinsics = [], []
    for cam, name in zip(cameras, names):
        K, _, _ = cam.to_opencv(width, height)
        intrinsics.append({"fl_x": float(K[0, 0]), "fl_y": float(K[1, 1]),
                           "cx": float(K[0, 2]) + 0.5, "cy": float(K[1, 2]) + 0.5,
                           "w": int(width), "h": int(height),
                           "near": float(cam.near), "far": float(cam.far)})
        frames.append({"file_path": name,
                       "transform_matrix": np.linalg.inv(cam.view_matrix).tolist()})
    if all(i == intrinsics[0] for i in intrinsics):
        doc = {**intrinsics[0], "frames": frames}
    else:
        doc = {"frames": [{**i, **f} for i, f in zip(intrinsics, frames)]}
    from .outputs import staged

    try:
        with staged(path) as tmp, open(tmp, "w", encoding="utf-8") as fh:
            json.dump(doc, fh, indent=1)
    except OSError as exc:
        raise OutputError(f"cannot write {path}: {exc.strerror or exc}") from None


def _quaternion_matrix(qw, qx, qy, qz) -> np.ndarray:
    """Rotation of the unit quaternion (w, x, y, z) (Hamilton convention, as COLMAP)."""
    n = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    if not n > 0:
        raise CameraError("a zero quaternion is not a rotation")
    w, x, y, z = qw / n, qx / n, qy / n, qz / n
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def read_colmap(folder: str | os.PathLike, near: float | None = None,
                far: float | None = None, bounds: ArrayLike | None = None) -> tuple:
    """Cameras of a COLMAP text model (``cameras.txt`` and ``images.txt`` in ``folder``):
    ``(cameras, image_names, sizes)`` in ``images.txt`` order. COLMAP stores no planes:
    ``near`` / ``far`` when given, else fitted to the scene's box ``bounds``
    (:meth:`hsr.Camera.fitted`), else 0.1 and 100. Camera models
    SIMPLE_PINHOLE (f, cx, cy) and PINHOLE (fx, fy, cx, cy); a model with lens distortion
    is refused (hsr renders pinholes), naming it. Raises :class:`~hsr.errors.CameraError`
    with the file and line on anything malformed."""
    cameras, names, sizes, fit = colmap_cameras(folder, near, far)
    return fitted_where(cameras, fit, bounds), names, sizes


def colmap_cameras(folder, near: float | None = None, far: float | None = None) -> tuple:
    """:func:`read_colmap` before any fitting: ``(cameras, image_names, sizes, fit)``,
    ``fit[k]`` True unless the call gave planes (COLMAP stores none)."""
    folder = os.fspath(folder)
    intrinsics = {}
    path = os.path.join(folder, "cameras.txt")
    for lineno, line in enumerate(_read_text(path, "COLMAP cameras file").splitlines(), 1):
        parts = line.split()
        if not parts or parts[0].startswith("#"):
            continue
        where = f"{path}:{lineno}"
        if len(parts) < 4:
            raise CameraError(f"{where}: expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS...")
        model = parts[1]
        if model not in COLMAP_MODELS:
            raise CameraError(f"{where}: camera model {model} has lens distortion or is not a "
                              f"pinhole; hsr renders {' and '.join(COLMAP_MODELS)} only "
                              f"(undistort the images with COLMAP first)")
        if parts[0] in intrinsics:
            raise CameraError(f"{where}: camera {parts[0]} is defined twice")
        w, h = _pixels(parts[2], "WIDTH", where), _pixels(parts[3], "HEIGHT", where)
        try:
            params = [float(p) for p in parts[4:]]
        except ValueError:
            raise CameraError(f"{where}: bad number in {line.strip()[:60]!r}") from None
        want = 3 if model == "SIMPLE_PINHOLE" else 4
        if len(params) != want:
            raise CameraError(f"{where}: {model} takes {want} parameters, got {len(params)}")
        fx, fy, cx, cy = (params[0], params[0], *params[1:]) if want == 3 else params
        for value, what in ((fx, "focal length"), (fy, "focal length")):
            _positive(value, what, where)
        for value, what in ((cx, "cx"), (cy, "cy")):
            _number(value, what, where)
        intrinsics[parts[0]] = (fx, fy, cx, cy, w, h)
    path = os.path.join(folder, "images.txt")
    lines = [(n, line) for n, line in enumerate(
        _read_text(path, "COLMAP images file").splitlines(), 1)
        if not line.startswith("#")]
    cameras, names, sizes, ids, fits = [], [], [], set(), []
    k = 0
    while k < len(lines):
        lineno, line = lines[k]
        parts = line.split()
        k += 2  # each image is two lines: the pose, then its 2-D points (may be empty)
        if not parts:
            k -= 1
            continue
        where = f"{path}:{lineno}"
        if len(parts) < 10:
            raise CameraError(f"{where}: expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME")
        try:
            q = [float(v) for v in parts[1:5]]
            t = np.array([float(v) for v in parts[5:8]])
        except ValueError:
            raise CameraError(f"{where}: bad number in {line.strip()[:60]!r}") from None
        if parts[0] in ids:
            raise CameraError(f"{where}: image {parts[0]} is listed twice")
        ids.add(parts[0])
        if not all(math.isfinite(v) for v in q) or not np.isfinite(t).all():
            raise CameraError(f"{where}: the pose has a NaN or infinite value")
        if parts[8] not in intrinsics:
            raise CameraError(f"{where}: camera {parts[8]} is not in cameras.txt")
        fx, fy, cx, cy, w, h = intrinsics[parts[8]]
        K = np.array([[fx, 0.0, cx - 0.5], [0.0, fy, cy - 0.5], [0.0, 0.0, 1.0]])
        near_k, far_k, fit = _planes({}, near, far, where)
        try:
            cam = Camera.from_opencv(K, _quaternion_matrix(*q), t, w, h, near=near_k,
                                     far=far_k)
        except CameraError as exc:
            raise CameraError(f"{where}: {exc}") from None
        cameras.append(cam)
        fits.append(fit)
        names.append(" ".join(parts[9:]))
        sizes.append((w, h))
    if not cameras:
        raise CameraError(f"{path}: no images")
    return cameras, names, sizes, fits
