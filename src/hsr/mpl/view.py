"""An mplot3d axes' view as an hsr camera: the same projection, in display pixels.

mplot3d projects data with one 4x4 matrix, ``ax.get_proj()`` = projection @ view @ world,
where *world* scales the axes' limits into a box of the box aspect's size (after the
axes' scales, log and so on), *view* is a rigid look-at and *projection* a perspective
of focal length ``f`` (or an orthographic box). Its projected x, y then go through the
axes' 2D ``transData`` to display pixels. hsr's world is that box; its camera has the
rigid view and an OpenGL projection that lands on the same display pixels, with near and
far fitted to the geometry (mplot3d's own depth is not OpenGL's, but any depth that
grows with distance orders the same).
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import HsrError
from ..scene.camera import Camera


class MplError(HsrError):
    """matplotlib integration: an axes or artist hsr cannot take."""


def box_matrix(ax) -> np.ndarray:
    """(4, 4) scaled data -> box coordinates (mplot3d's world transformation)."""
    from mpl_toolkits.mplot3d import proj3d

    aspect = ax._roll_to_vertical(ax._box_aspect)
    limits = ax._get_scaled_limits() if hasattr(ax, "_get_scaled_limits") else ax.get_w_lims()
    return proj3d.world_transformation(*limits, pb_aspect=aspect)


def scaled(ax, points: np.ndarray) -> np.ndarray:
    """(N, 3) data -> the axes' scaled coordinates (log axes and so on; linear: the same)."""
    out = np.empty_like(points, dtype=np.float64)
    for k, axis in enumerate((ax.xaxis, ax.yaxis, ax.zaxis)):
        out[:, k] = axis.get_transform().transform(points[:, k])
    return out


def to_box(ax, points: np.ndarray) -> np.ndarray:
    """(N, 3) data points -> (N, 3) box coordinates, hsr's world for this axes."""
    world = box_matrix(ax)
    return scaled(ax, points) @ world[:3, :3].T + world[:3, 3]


def _display_affine(ax) -> tuple:
    """(sx, tx, sy, ty): display = (sx x + tx, sy y + ty) for mplot3d's projected x, y."""
    corners = ax.transData.transform([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    sx, shear_x = corners[1] - corners[0]
    shear_y, sy = corners[2] - corners[0]
    if abs(shear_x) > 1e-9 * abs(sx) or abs(shear_y) > 1e-9 * abs(sy) or sx <= 0 or sy <= 0:
        raise MplError("hsr.mpl: the axes' 2D transform is not an axis-aligned scale")
    return float(sx), float(corners[0][0]), float(sy), float(corners[0][1])


def view_and_focal(ax) -> tuple:
    """(view (4, 4) rigid box -> eye, focal length or inf) such that projection @ view @
    box_matrix(ax) is ``ax.get_proj()`` (checked: a matplotlib whose projection differs
    is refused rather than drawn wrong)."""
    M = ax.get_proj()
    Q = M @ np.linalg.inv(box_matrix(ax))
    focal = float(ax._focal_length)
    view = np.eye(4)
    if math.isinf(focal):
        rows = (Q[0], Q[1], -Q[2])
    else:
        rows = (Q[0], Q[1], -Q[3])
    for k, row in enumerate(rows):
        view[k] = row / np.linalg.norm(row[:3])
    ok = np.allclose(view[:3, :3] @ view[:3, :3].T, np.eye(3), atol=1e-9) and \
        np.linalg.det(view[:3, :3]) > 0
    if ok:
        from mpl_toolkits.mplot3d import proj3d

        d = float(ax._dist)
        proj = proj3d._ortho_transformation(-d, d) if math.isinf(focal) else \
            proj3d._persp_transformation(-d, d, focal)
        ok = np.allclose(proj @ view, Q, rtol=1e-9, atol=1e-12 * np.abs(Q).max())
    if not ok:
        import matplotlib

        raise MplError(f"hsr.mpl does not know the 3D projection of matplotlib "
                       f"{matplotlib.__version__}")
    return view, focal


def camera_for(ax, box_points: np.ndarray, width: int, height: int) -> Camera:
    """The hsr camera that draws ``ax``'s view onto a ``width`` x ``height`` display (the
    figure's pixels, y up), with near and far fitted around ``box_points`` (N, 3)."""
    view, focal = view_and_focal(ax)
    sx, tx, sy, ty = _display_affine(ax)
    depth = -(box_points @ view[2, :3] + view[2, 3]) if len(box_points) else np.ones(1)
    far = float(depth.max()) if len(depth) else 1.0
    proj = np.zeros((4, 4))
    if math.isinf(focal):
        d = float(ax._dist)
        # mplot3d: x = x_eye / d, then display; glOrtho: x_ndc = P00 x_eye + P03.
        near = float(depth.min())
        span = max(far - near, 1e-9 * max(abs(far), 1.0))
        near, far = near - 0.01 * span, far + 0.01 * span
        proj[0, 0], proj[0, 3] = 2.0 * sx / (d * width), 2.0 * tx / width - 1.0
        proj[1, 1], proj[1, 3] = 2.0 * sy / (d * height), 2.0 * ty / height - 1.0
        proj[2, 2], proj[2, 3] = -2.0 / (far - near), -(far + near) / (far - near)
        proj[3, 3] = 1.0
    else:
        # mplot3d: x = f x_eye / -z_eye; glFrustum: x_ndc = (P00 x_eye + P02 z_eye) / -z_eye.
        far = max(far, 1e-6) * 1.01
        front = depth[depth > 0]
        near = float(front.min()) * 0.99 if len(front) else far * 1e-3
        near = max(near, far * 1e-6)
        proj[0, 0], proj[0, 2] = 2.0 * sx * focal / width, 1.0 - 2.0 * tx / width
        proj[1, 1], proj[1, 2] = 2.0 * sy * focal / height, 1.0 - 2.0 * ty / height
        proj[2, 2], proj[2, 3] = -(far + near) / (far - near), -2.0 * far * near / (far - near)
        proj[3, 2] = -1.0
    return Camera.from_matrices(view, proj)
