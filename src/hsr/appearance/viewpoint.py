"""The first look at a model: the viewpoint that shows the most of its shape.

A fixed three-quarter view (azimuth 35, elevation 25 degrees) shows a box well and a
model authored facing -Z from behind (spot's back), or a CAD part's largest flat side
(fandisk as one grey shape). View selection in the literature scores candidate
viewpoints by what their images show: viewpoint entropy of the visible faces' projected
areas (Vazquez, Feixas, Sbert and Heidrich 2001), visible mean curvature or mesh saliency
(Lee, Varshney and Jacobs 2005), and people prefer views from the front-side and slightly
above (Blanz, Tarr and Buelthoff 1999, "canonical views").

hsr scores each candidate by the **projected total curvature**: in a small z-buffer
render, the sum over neighbouring pixel pairs that both show the model of the
difference between the two faces' unit normals (|n_p - n_q|, about the angle between
them). A smooth, gently curved side (a rump, the back of a head) adds little; creases,
ears, noses, horns and a CAD part's feature edges add much, and a view straight at a
plane adds nothing. Viewpoint entropy was tried first and picked the backs of spot and
the bunny and top-down views: on a finely tessellated mesh a pixel is about a face, so
the entropy measures the covered area rather than the detail.

The candidates are eight azimuths (35 + 45 k degrees, so the old default is the first
and a model turned by 90 or 180 degrees about +Y gets the same view turned with it) at
elevations 15 and 35, keeping +Y up; the first best wins, so a model with no preferred
side keeps the old three-quarter view. Each is a 96 x 72 render of face ids: about 16
renders of the model's faces, so models over :data:`FACE_BUDGET` faces get the eight
azimuths at elevation 25 only, and those over 8x that the fixed default (see
:func:`best_view`).
"""

from __future__ import annotations

import numpy as np

from ..geometry.stage import prepare
from ..geometry.state import RenderState
from ..parallel import Workers
from ..scene.camera import Camera
from ..scene.mesh import SceneLike, as_scene, normal_matrix
from ..scene.views import (
    DEFAULT_VIEW,
    MARGIN,
    UpAxis,
    default,
    direction,
    model_points,
    model_up,
    up_vector,
)

AZIMUTHS = tuple(35.0 + 45.0 * k for k in range(8))
ELEVATIONS = (15.0, 35.0)
SIZE = (96, 72)
# Faces x candidate renders above which fewer candidates are tried: 16 renders of a
# 250k-face model cost about as much as one 1080p render of 4M faces (~0.15 s here).
FACE_BUDGET = 250_000


def candidates(n_faces: int) -> list:
    """The (azimuth, elevation) pairs tried for a model of ``n_faces`` faces, in order of
    preference on ties."""
    if n_faces <= FACE_BUDGET:
        return [(az, el) for el in ELEVATIONS for az in AZIMUTHS]
    if n_faces <= 8 * FACE_BUDGET:
        return [(az, DEFAULT_VIEW[1]) for az in AZIMUTHS]
    return [DEFAULT_VIEW]


def best_view(model: SceneLike, fov_y: float = 45.0, workers: Workers | None = None,
              up_axis: UpAxis | None = None) -> tuple:
    """``(azimuth, elevation)`` in degrees (as :func:`hsr.views.direction` takes them) of
    the candidate view of ``model`` (a Mesh or Scene) with the largest projected total
    curvature, see the module. Deterministic; about 16 renders of 96 x 72 (fewer for
    models over :data:`FACE_BUDGET` faces). Raises :class:`~hsr.errors.MeshError` for
    something that is not a mesh or scene. ``up_axis``: ``"y"``, ``"z"`` or None for the
    model's own (:meth:`hsr.Scene.up_axis`)."""
    scene = as_scene(model)
    up = model_up(scene, up_axis)
    tried = candidates(scene.n_faces)
    if len(tried) == 1:
        return tried[0]
    normals = _face_normals(scene)
    points = model_points(scene)
    bounds = np.stack([points.min(axis=0), points.max(axis=0)])
    workers = workers or Workers()
    width, height = SIZE
    best, best_score = tried[0], -1.0
    for az, el in tried:
        camera = Camera.frame(bounds, direction(az, el, up), tuple(up_vector(up)),
                              fov_y, margin=MARGIN, aspect=width / height, fit="points",
                              points=points)
        score = projected_curvature(_face_ids(scene, camera, width, height, workers),
                                    normals)
        if score > best_score:
            best, best_score = (az, el), score
    return best


def first_look(model: SceneLike, aspect: float = 1.0, fov_y: float = 45.0,
               up_axis: UpAxis | None = None) -> Camera:
    """The camera ``hsr render MODEL`` and ``hsr.render(model)`` start from: the model
    framed as :func:`hsr.views.default` frames it (as large as it fits in an image of
    ``aspect``), from :func:`best_view`, with ``up_axis`` (``"y"`` or ``"z"``: a Z-up
    scan or CAD part stands up; None, the default: the one the model declares, see
    :func:`hsr.load`) up. Raises :class:`~hsr.errors.MeshError` for
    something that is not a mesh or scene and :class:`~hsr.errors.CameraError` for an
    aspect or fov out of range or another up axis."""
    scene = as_scene(model)
    up = model_up(scene, up_axis)
    view = best_view(scene, fov_y, up_axis=up)
    return default(scene, aspect, fov_y, view=view, up_axis=up)


def projected_curvature(face_id: np.ndarray, normals: np.ndarray) -> float:
    """Sum of |n_p - n_q| over the horizontally and vertically neighbouring pixels p, q of
    ``face_id`` ((H, W), -1 background) that both show a face; ``normals`` (F, 3) unit
    face normals by face id."""
    covered = face_id >= 0
    n = normals[np.where(covered, face_id, 0)]
    total = 0.0
    for a, b, both in ((n[:, 1:], n[:, :-1], covered[:, 1:] & covered[:, :-1]),
                       (n[1:], n[:-1], covered[1:] & covered[:-1])):
        total += float(np.linalg.norm(a[both] - b[both], axis=-1).sum())
    return total


def _face_normals(scene) -> np.ndarray:
    """(F, 3) unit world-space normals as wound, in the scene's global face order (zero
    for degenerate faces, and for faces too large for float64's squares: such a model
    cannot be framed anyway, and Camera.frame says so)."""
    parts = []
    with np.errstate(over="ignore", invalid="ignore"):
        for inst in scene.instances:
            turned = inst.mesh.face_normals() @ normal_matrix(inst.model).T
            length = np.linalg.norm(turned, axis=1, keepdims=True)
            usable = (length > 0) & np.isfinite(length)
            parts.append(np.divide(turned, length, out=np.zeros_like(turned), where=usable))
    return np.concatenate(parts)


def _face_ids(scene, camera, width, height, workers) -> np.ndarray:
    """(H, W) int32 face ids of a plain z-buffer render (no shading)."""
    from ..algorithms import zbuffer

    state = RenderState()
    view_proj = camera.projection_matrix(width / height) @ camera.view_matrix
    screen = prepare(scene, view_proj, width, height, state, {}, workers, deferred=True)
    return zbuffer.resolve(screen, state, workers=workers).face_id
