"""Visibility queries, one call each: which faces a camera shows
(:func:`visible_faces`), which vertices or arbitrary points it sees
(:func:`visible_vertices`, :func:`visible_points`), and the faces x views table of pixel
counts for many cameras, with how well each view sees each face
(:func:`visibility_matrix`).

Why vertices and points are tested with rays and not looked up in a depth buffer: a
vertex on a silhouette or a crease lies on the edge between a face that shows and one
that does not, and its pixel centre (x + 0.5, y + 0.5) is generally not where the vertex
projects, so the buffer holds the depth of whatever covers that pixel centre, maybe a
face behind the silhouette, or the near face of a crease a hair in front. Any tolerance
on that comparison misjudges some vertices. The exact question is geometric: does the
open segment from the eye to the point meet a surface? :meth:`hsr.RayScene.occluded`
answers it exactly (watertight triangle test); the segment is shortened by ``tolerance``
of its length at the point's end, so the point's own faces do not hide it.
"""

from __future__ import annotations

import os
import sys
from typing import Any

import numpy as np
from numba import njit
from numpy.typing import ArrayLike

from ..algorithms.raycast import row_rays
from ..scene.camera import Camera
from ..scene.mesh import SceneLike, as_scene
from .count import VisibilityError, cameras_for, check_size
from .rays import RayScene

__all__ = ["write_visibility", "visible_faces", "visible_vertices", "visible_points",
           "visibility_matrix", "project_points", "VisibilityMatrix", "scene_vertices"]


def _camera(camera):
    from ..scene.camera import Camera

    if not isinstance(camera, Camera):
        raise VisibilityError(f"camera must be an hsr.Camera, got {type(camera).__name__}")
    return camera


def _scene(scene, partitioned: bool = False):
    """The Scene a query works on; a partitioned scene (a store or its path) only where
    ``partitioned`` (the queries that composite, see :mod:`hsr.batch.sortlast`)."""
    from ..scene.load import load_scene
    from ..scene.partitioned import PartitionedScene

    if isinstance(scene, RayScene):
        return scene.scene
    if isinstance(scene, (str, os.PathLike)):
        scene = load_scene(scene)
    if isinstance(scene, PartitionedScene):
        if partitioned:
            return scene
        raise VisibilityError(f"{scene.path} is a partitioned scene: face_visibility and "
                              f"visibility_matrix take it, this query needs the scene in "
                              f"memory")
    return as_scene(scene)


def visible_faces(scene: SceneLike, camera: Camera, width: int, height: int,
                  exact: bool = False, **render_options) -> tuple:
    """``(face_ids, pixel_counts)``: the global ids (ascending, int64) of the faces that
    own at least one pixel centre of ``camera``'s ``width`` x ``height`` image, and how
    many (int64): exactly what :func:`hsr.render` shows, with the same
    ``render_options`` (``cull``, ``depth_func``, ``algorithm``, ...).

    ``exact=True``: ``(face_ids, areas)``, every face with a visible part however small
    (no pixel centre needed) and its visible area in px^2 (float64), from
    :func:`hsr.visible_regions` (``render_options``: its depth state).

    Raises what :func:`hsr.render` (or :func:`hsr.visible_regions`) raises."""
    from ..render import render

    if exact:
        from .regions import visible_regions

        regions = visible_regions(_scene(scene), _camera(camera), width, height,
                                  **render_options)
        return regions.face_id, regions.area

    frame = render(_scene(scene), _camera(camera), width, height, color=False,
                   **render_options)
    ids = frame.face_id[frame.face_id >= 0]
    faces, counts = np.unique(ids, return_counts=True)
    return faces.astype(np.int64), counts.astype(np.int64)


def scene_vertices(scene: SceneLike) -> np.ndarray:
    """(V, 3) float64 world positions of every vertex of every instance, in scene order
    (instance 0's vertices, then instance 1's, ...), as :func:`visible_vertices` numbers
    them."""
    scene = _scene(scene)
    parts = [inst.mesh.positions @ inst.model[:3, :3].T + inst.model[:3, 3]
             for inst in scene.instances]
    return np.concatenate(parts) if parts else np.zeros((0, 3))


def project_points(camera: Camera, points: ArrayLike, width: int, height: int,
                   convention: str = "hsr") -> tuple:
    """``(pixels, in_frustum)`` for (N, 3) world ``points``: (N, 2) float64 window
    coordinates and (N,) bool.

    ``convention="hsr"``: x right, y down, pixel (x, y) centred at (x + 0.5, y + 0.5)
    (the top-left pixel covers [0, 1) x [0, 1)); ``"opencv"``: pixel centres on
    integers, i.e. hsr's minus 0.5 (what ``cv2.projectPoints`` returns for
    ``camera.to_opencv(width, height)``). ``in_frustum``: the point lies inside the view
    volume (the image rectangle between the near and far planes); points behind the
    camera get NaN pixels."""
    from ..geometry.viewport import check_size as check_image

    camera = _camera(camera)
    check_image(width, height)
    if convention not in ("hsr", "opencv"):
        raise VisibilityError(f"convention must be 'hsr' or 'opencv', got {convention!r}")
    points = _points(points)
    view_proj = camera.projection_matrix(width / height) @ camera.view_matrix
    pos_clip = points @ view_proj[:3, :3].T + view_proj[:3, 3]
    w_clip = points @ view_proj[3, :3] + view_proj[3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        ndc = pos_clip / w_clip[:, None]
    front = w_clip > 0
    inside = front & np.all(np.abs(pos_clip) <= w_clip[:, None], axis=1)
    xy_window = np.empty((len(points), 2))
    xy_window[:, 0] = (ndc[:, 0] + 1.0) * 0.5 * width
    xy_window[:, 1] = (1.0 - ndc[:, 1]) * 0.5 * height
    xy_window[~front] = np.nan
    if convention == "opencv":
        xy_window -= 0.5
    return xy_window, inside


def _points(points) -> np.ndarray:
    try:
        given = np.asarray(points)
        if given.dtype.kind in "cbmMSUV":  # complex (its imaginary part would be lost),
            raise TypeError(f"dtype {given.dtype}")  # booleans, times, text, records
        array = np.asarray(given, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise VisibilityError(f"points must be an (N, 3) array of real numbers "
                              f"({exc})") from None
    if array.ndim != 2 or array.shape[1] != 3:
        raise VisibilityError(f"points must have shape (N, 3), got {array.shape}")
    if len(array) == 0:
        raise VisibilityError("points is empty: give at least one point")
    if not np.isfinite(array).all():
        k = int(np.argmax(~np.isfinite(array).all(axis=1)))
        raise VisibilityError(f"points must be finite; point {k} is {array[k].tolist()}")
    return array


def _check_tolerance(tolerance) -> float:
    if isinstance(tolerance, bool) or not isinstance(tolerance, (int, float, np.floating)) \
            or not 0.0 <= tolerance < 1.0:
        raise VisibilityError(f"tolerance must be a number in [0, 1), got {tolerance!r}")
    return float(tolerance)


def _segments_clear(rays: RayScene, camera, points, tolerance, progress) -> np.ndarray:
    """(N,) bool: the segment from the eye (orthographic: from the point's foot on the
    plane of the eye) to each point, cut ``tolerance`` of its length short of the
    point, meets no surface."""
    if camera.is_orthographic:
        forward = camera.forward
        depth = (points - np.asarray(camera.eye, dtype=np.float64)) @ forward
        origins = points - depth[:, None] * forward
    else:
        origins = np.broadcast_to(np.asarray(camera.eye, dtype=np.float64), points.shape)
    directions = points - origins
    clear = np.ones(len(points), dtype=bool)
    # A point at the eye has no segment to block.
    real = directions.any(axis=1)
    if real.any():
        clear[real] = ~rays.occluded(origins[real], directions[real], 0.0, 1.0 - tolerance,
                                     progress=progress)
    return clear


def visible_vertices(scene: SceneLike, camera: Camera, width: int, height: int,
                     tolerance: float = 1e-4, progress: bool | None = None) -> np.ndarray:
    """(V,) bool over the scene's vertices (:func:`scene_vertices` order: instances in
    scene order, each mesh's vertices in its order): the vertex lies inside
    ``camera``'s view volume for a ``width`` x ``height`` image, and the open segment
    from the eye to it, shortened by ``tolerance`` of its length, hits no surface (see
    the module notes for why this is a ray test and not a depth-buffer lookup).

    ``scene``: a Mesh, Scene, path, or a :class:`~hsr.RayScene` (its BVH is reused, the
    fast way to ask about many cameras). Geometry between the eye and the near plane
    counts as occluding here (the render clips it). Raises
    :class:`~hsr.visibility.VisibilityError` for a bad camera, size or tolerance."""
    rays = scene if isinstance(scene, RayScene) else RayScene(_scene(scene))
    return visible_points(rays, camera, scene_vertices(rays.scene), width, height,
                          tolerance, progress=progress)[1]


def visible_points(scene: SceneLike, camera: Camera, points: ArrayLike, width: int,
                   height: int, tolerance: float = 1e-4, convention: str = "hsr",
                   progress: bool | None = None) -> tuple:
    """``(pixels, visible)`` for (N, 3) world ``points`` (a point cloud to colour from a
    photo, landmarks, sensor positions): pixels (N, 2) float64 in ``convention`` (see
    :func:`project_points`: ``"hsr"`` x right, y down, pixel (x, y) centred at
    (x + 0.5, y + 0.5); ``"opencv"`` the same minus 0.5, as ``cv2.projectPoints``), and
    visible (N,) bool: inside the view volume and not hidden, by the segment test of
    :func:`visible_vertices`. Raises :class:`~hsr.visibility.VisibilityError` for an
    empty or malformed point set, a bad camera, size or tolerance."""
    tolerance = _check_tolerance(tolerance)
    pixels, inside = project_points(camera, points, width, height, convention)
    points = _points(points)
    rays = scene if isinstance(scene, RayScene) else RayScene(_scene(scene))
    visible = np.zeros(len(points), dtype=bool)
    if inside.any():
        visible[inside] = _segments_clear(rays, camera, points[inside], tolerance, progress)
    return pixels, visible


class VisibilityMatrix:
    """What :func:`visibility_matrix` returns: ``counts``, a
    ``scipy.sparse.csr_matrix`` (n_faces x n_views, int64) of the pixels where each
    face is visible in each view; with quality terms, ``cosine`` and ``distance``, csr
    matrices of the same pattern holding each (face, view)'s mean cosine between the
    face's normal (as wound) and the direction to the eye, and mean distance from the eye
    (world units), over its pixels; and ``cameras``, the views' cameras."""

    def __init__(self, counts: Any, cameras: list, cosine: Any = None,
                 distance: Any = None) -> None:
        self.counts, self.cameras, self.cosine, self.distance = counts, cameras, cosine, distance

    @property
    def shape(self):
        return self.counts.shape

    def best_view(self) -> np.ndarray:
        """(n_faces,) int64: for each face the view that sees it best, -1 where none
        does: the most pixels, or with quality terms the most pixels times the mean
        cosine (texturing's common score: projected area), falling back to the most
        pixels for a face that every view sees from behind."""
        pixels = self.counts.astype(np.float64)
        best = np.asarray(pixels.argmax(axis=1)).ravel()
        if self.cosine is not None:
            score = pixels.multiply(self.cosine.maximum(0.0)).tocsr()
            front = np.asarray(score.max(axis=1).todense()).ravel() > 0
            best = np.where(front, np.asarray(score.argmax(axis=1)).ravel(), best)
        seen = np.diff(self.counts.indptr) > 0
        return np.where(seen, best, -1).astype(np.int64)


def _view_columns(scene, camera, width, height, options, quality, workspace):
    """One view: (faces, counts[, cosine sums, distance sums]) of the faces it shows."""
    from ..render import render

    frame = render(scene, camera, width, height, color=False, workspace=workspace,
                   **options)
    return frame_columns(frame, camera, quality)


def frame_columns(frame, camera, quality: bool) -> tuple:
    """(faces, counts[, cosine sums, distance sums]) of the faces a frame shows (an
    :class:`hsr.Frame`, or a composited one with normals and distance when ``quality``)."""
    height, width = frame.face_id.shape
    face_id = frame.face_id.ravel()
    shown = face_id >= 0
    ids = face_id[shown]
    faces, inverse, counts = np.unique(ids, return_inverse=True, return_counts=True)
    if not quality:
        return faces, counts
    normals = frame.normals.reshape(-1, 3)[shown].astype(np.float64)
    distance = frame.distance.ravel()[shown].astype(np.float64)
    view_proj = camera.projection_matrix(width / height) @ camera.view_matrix
    cosine = _towards_eye_cosine(np.linalg.inv(view_proj), width, height,
                                 np.flatnonzero(shown), normals)
    return (faces, counts, np.bincount(inverse, cosine, len(faces)),
            np.bincount(inverse, distance, len(faces)))


@njit(cache=True, nogil=True)
def _towards_eye_cosine(inv_view_proj, width, height, pixels, normals):
    """Per covered pixel (``pixels``: flat indices, row 0 the top), the cosine between its
    normal and the unit direction back along its ray: the ray caster's pixel ray
    (:func:`hsr.algorithms.raycast.row_rays`, near plane to far plane), made a row at a
    time, normalised and turned around. (In NumPy, rays for every pixel of the image,
    it took 41 ms of a 512 x 512 view's 78 with quality terms, the render 6.)"""
    rays = np.empty((6, width))
    no_eye = np.zeros(3)
    out = np.empty(len(pixels))
    row = -1
    for k in range(len(pixels)):
        r, c = divmod(pixels[k], width)
        if r != row:  # the pixels come in row order (np.flatnonzero): each row once
            row_rays(inv_view_proj, width, height, r, 0, width, no_eye, False, rays)
            row = r
        dx, dy, dz = rays[3, c], rays[4, c], rays[5, c]
        length = np.sqrt(dx * dx + dy * dy + dz * dz)
        out[k] = -(normals[k, 0] * dx + normals[k, 1] * dy + normals[k, 2] * dz) / length
    return out


def _columns(scene, cameras, width, height, options, quality, client, progress) -> list:
    """The columns of every view of an in-memory scene, here or on a Dask client."""
    from ..parallel import progress_bar
    from .count import spread_views

    columns: list = [None] * len(cameras)
    with progress_bar(progress, len(cameras), "visibility") as bar:
        if client is None:
            for j, cam in enumerate(cameras):
                columns[j] = view_group_columns(scene, [cam], width, height, options,
                                                quality)[0]
                bar.update(1)
        else:
            def take(k, group):
                columns[k:k + len(group)] = group

            spread_views(client, view_group_columns, scene, cameras,
                         (width, height, options, quality), take, bar)
    return columns


def view_group_columns(scene, cameras, width, height, options, quality) -> list:
    """A Dask task (and the local loop): the columns of a group of views, one thread."""
    from ..parallel import Workspace

    with Workspace(1) as workspace:
        return [_view_columns(scene, cam, width, height, options, quality, workspace)
                for cam in cameras]


def visibility_matrix(scene: SceneLike, views: Any, size: int | tuple = 512, *,
                      client: Any = None, quality: bool = False,
                      near: float | None = None, far: float | None = None,
                      progress: bool | None = None, exact: bool = False,
                      **render_options) -> VisibilityMatrix:
    """The faces x views table of visible pixel counts (a :class:`VisibilityMatrix`,
    ``.counts`` a ``scipy.sparse.csr_matrix``), for ``views`` as
    :func:`~hsr.visibility.face_visibility` takes them (``sphere:N``, ``hemisphere:N``,
    ``orbit:N``, a transforms.json or COLMAP folder, cameras, or a list of these) at
    ``size`` (``R`` or ``(W, H)``), rendered with ``render_options``. Column ``j`` is
    ``np.bincount(render(scene, cameras[j], W, H).face_id)`` over the faces; the row sums
    are :func:`~hsr.visibility.face_visibility`. ``quality``: also the mean cosine and
    mean distance per (face, view) (see :class:`VisibilityMatrix`), for texturing's view
    selection. ``client``: a ``distributed.Client``; one task per group of views, only
    the sparse columns come back. ``exact=True``: ``.counts`` holds visible areas in px^2
    (float64) from :func:`hsr.visible_regions`, every face with a visible part however
    small (``render_options``: its depth state), and the quality terms are means over the
    visible area (:meth:`hsr.Regions.quality`).

    Raises :class:`~hsr.visibility.VisibilityError` for bad views or size, and what
    :func:`hsr.render` raises for bad render options."""
    import scipy.sparse

    from ..batch.sortlast import render_partitioned
    from ..render import render
    from ..scene.partitioned import PartitionedScene
    from .count import check_opaque

    scene = _scene(scene, partitioned=True)
    width, height = check_size(size)
    if not isinstance(quality, (bool, np.bool_)):
        raise VisibilityError(f"quality must be True or False, got {quality!r}")
    for name in ("into", "counts", "hidden_line", "color", "workspace", "threads"):
        if name in render_options:
            raise VisibilityError(f"{name} is not an option of visibility_matrix")
    cameras = cameras_for(scene, views, width / height, near, far)
    if progress is None:
        progress = sys.stderr.isatty()
    if exact:
        if isinstance(scene, PartitionedScene):
            raise VisibilityError("exact=True does not take a partitioned scene (yet)")
        check_opaque(scene)
        columns = _exact_columns(scene, cameras, width, height, render_options, quality,
                                 client, progress)
    elif isinstance(scene, PartitionedScene):
        # Sort-last: the counts are taken from the composited frames (hsr.batch.sortlast).
        frames = render_partitioned(scene, cameras, width, height,
                                    outputs=("normals", "distance") if quality else (),
                                    client=client, **render_options)
        columns = [frame_columns(f, cam, quality) for f, cam in zip(frames, cameras)]
    else:
        check_opaque(scene)
        render(scene, cameras[0], 1, 1, threads=1, **render_options)  # bad options: now
        columns = _columns(scene, cameras, width, height, render_options, quality, client,
                           progress)
    n_faces = scene.n_faces

    def matrix(part, dtype):
        data = np.concatenate([c[part] for c in columns]).astype(dtype)
        rows = np.concatenate([c[0] for c in columns]).astype(np.int64)
        cols = np.repeat(np.arange(len(columns)), [len(c[0]) for c in columns])
        return scipy.sparse.csr_matrix((data, (rows, cols)), shape=(n_faces, len(columns)))

    counts = matrix(1, np.float64 if exact else np.int64)
    if not quality:
        return VisibilityMatrix(counts, cameras)
    # Means: the sums over each (face, view)'s pixels divided by its count, on the same
    # sparsity pattern (every stored count is >= 1).
    cosine, distance = matrix(2, np.float64), matrix(3, np.float64)
    for m in (cosine, distance):
        m.data /= counts.data
    return VisibilityMatrix(counts, cameras, cosine, distance)


def _exact_columns(scene, cameras, width, height, state, quality, client,
                   progress) -> list:
    """(face ids, areas[, area-weighted cosine and distance sums]) of each view's visible
    regions, here or on ``client``."""
    from ..parallel import progress_bar
    from .count import exact_state, region_columns, spread_views

    state = exact_state(scene, cameras[0], state)
    columns: list = [None] * len(cameras)
    with progress_bar(progress, len(cameras), "visibility") as bar:
        if client is not None:
            def take(first, group):
                columns[first:first + len(group)] = group

            spread_views(client, region_columns, scene, cameras,
                         (width, height, state, quality), take, bar)
        else:
            for k, camera in enumerate(cameras):
                columns[k] = region_columns(scene, [camera], width, height, state,
                                            quality)[0]
                bar.update(1)
    return columns


def write_visibility(scene, cameras, size, what: str, points, out: str, *, quality=False,
                     tolerance=1e-4, client=None, progress=None, exact=False,
                     **render_options) -> str:
    """``hsr visibility``: compute ``what`` (``faces``, ``vertices`` or ``points``) for
    every camera and write ``out``; returns the summary line.

    ``.npz``: ``face``, ``view``, ``pixels`` (COO triplets of the faces x views matrix,
    with ``cosine`` and ``distance`` when ``quality``) and ``shape``; or ``visible``
    (N, views) bool for vertices and points, with ``pixels`` (views, N, 2) in hsr's
    window convention for points. ``.csv``: one row per visible pair: ``face,view,pixels``
    (``,cosine,distance``), ``vertex,view``, or ``point,view,x,y``. ``exact``: faces
    with their visible ``area`` (px^2, float64) in place of ``pixels``."""
    width, height = size
    ext = os.path.splitext(out)[1].lower()
    n_views = len(cameras)
    if what == "faces":
        vm = visibility_matrix(scene, cameras, size, client=client, quality=quality,
                               progress=progress, exact=exact, **render_options)
        coo = vm.counts.tocoo()
        columns = {"face": coo.row.astype(np.int64), "view": coo.col.astype(np.int64)}
        if exact:
            columns["area"] = coo.data.astype(np.float64)
        else:
            columns["pixels"] = coo.data.astype(np.int64)
        if quality:
            columns["cosine"] = vm.cosine.tocoo().data
            columns["distance"] = vm.distance.tocoo().data
        per_view = np.diff(vm.counts.tocsc().indptr)
        total, noun = scene.n_faces, "faces"
    else:
        rays = RayScene(scene)
        targets = scene_vertices(scene) if what == "vertices" else _points(points)
        visible = np.zeros((len(targets), n_views), dtype=bool)
        pixels = np.zeros((n_views, len(targets), 2))
        for j, cam in enumerate(cameras):
            pixels[j], visible[:, j] = visible_points(rays, cam, targets, width, height,
                                                      tolerance, progress=False)
        per_view = visible.sum(axis=0)
        total, noun = len(targets), what
        index, view = np.nonzero(visible)
        key = "vertex" if what == "vertices" else "point"
        columns = {key: index.astype(np.int64), "view": view.astype(np.int64)}
        if what == "points":
            columns["x"], columns["y"] = pixels[view, index, 0], pixels[view, index, 1]
    _write_table(out, ext, columns, (total, n_views),
                 None if what == "faces" else visible,
                 pixels if what == "points" else None)
    low, mid, high = (int(per_view.min()), float(np.median(per_view)), int(per_view.max()))
    return (f"{n_views} views at {width}x{height}: {noun} visible per view min {low:,} / "
            f"median {mid:,.0f} / max {high:,} of {total:,}; wrote {out}")


def _write_table(out, ext, columns, shape, visible, pixels) -> None:
    """The table of visible pairs as ``.csv`` or ``.npz``; an ``.npz`` is also the sparse
    (items x views) matrix of the pairs in SciPy's COO layout (``format``, ``row``,
    ``col``, ``data``, ``shape``), so ``scipy.sparse.load_npz`` reads it: the pixel
    counts for faces, 1 for each visible vertex or point."""
    from ..scene.outputs import staged

    with staged(out) as tmp:
        if ext == ".npz":
            names = list(columns)
            row, col = columns[names[0]], columns["view"]
            data = (columns["pixels"] if "pixels" in columns else columns["area"]
                    if "area" in columns else np.ones(len(row), np.uint8))
            arrays = dict(format=np.asarray("coo"), row=row, col=col, data=data,
                          shape=np.asarray(shape, dtype=np.int64))
            if visible is None:
                arrays.update(columns)
            else:
                arrays["visible"] = visible
                if pixels is not None:
                    arrays["pixels"] = pixels
            np.savez_compressed(tmp, **arrays)
        else:
            names = list(columns)
            table = np.column_stack([columns[n] for n in names]) if len(columns[names[0]]) \
                else np.zeros((0, len(names)))
            formats = ["%d" if np.issubdtype(columns[n].dtype, np.integer) else "%.9g"
                       for n in names]
            np.savetxt(tmp, table, fmt=formats, delimiter=",", header=",".join(names),
                       comments="")
