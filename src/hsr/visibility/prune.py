"""Removing hidden geometry: keep the faces (or whole instances) that some view sees,
optionally grown by K edge-rings, and build the smaller scene with face order kept.
``verify`` measures what the removal changed from viewpoints the decision did not use.

The decision is only as fine as its samples: a face seen by no pixel centre of any view
is removed even if a sliver of it shows between the samples (``keep_neighbors`` guards
against that; ``verify`` counts it, never hides it).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..choices import Algorithm
from ..geometry.weld import weld
from ..scene.mesh import Mesh, Scene, SceneLike, as_scene, cached_while_same
from ..scene.partitioned import PartitionedScene
from .count import VisibilityError, cameras_for, check_size, face_visibility, per_object

__all__ = ["prune", "decide", "Decision", "auto_size", "VisibilityWarning", "keep_faces",
           "grow_rings", "subset_scene", "verify", "LEVELS"]

LEVELS = ("faces", "objects")
MAX_RINGS = 1000


# The automatic decision (views "auto", see decide): a Fibonacci sphere of AUTO_FIRST
# directions, then rounds of fresh random ones, each at least AUTO_ROUND views and half as
# many as all before it, until a round changes nothing; two rings kept unless told.
AUTO_FIRST = 32
AUTO_ROUND = 16
AUTO_RINGS = 2
AUTO_MAX_VIEWS = 2048
# Automatic size: about one pixel per face (sqrt of the face count, to a multiple of 128)
# within these bounds.
AUTO_SIZE = (256, 2048)
# Mixed into the seed of the automatic rounds, so their directions are not those
# verify draws from the same seed.
AUTO_STREAM = 0x5EED_0F_A070


class VisibilityWarning(UserWarning):
    """An automatic decision stopped at its view limit before a round confirmed it."""


@dataclass(frozen=True)
class Decision:
    """What :func:`decide` found: ``counts`` (per face, visible pixels over all views),
    ``keep`` (per face, bool), the ``cameras`` rendered (in order) at ``size`` (width,
    height), ``last_round`` (the views of the final round: all of them for fixed views)
    and ``converged`` (False only when ``auto`` stopped at ``max_views`` before a round
    confirmed the kept faces)."""

    counts: np.ndarray
    keep: np.ndarray
    cameras: tuple
    size: tuple
    last_round: int
    converged: bool

    @property
    def views(self) -> int:
        """How many views were rendered."""
        return len(self.cameras)


def auto_size(scene: Scene) -> int:
    """The side of the square views of ``size="auto"``: about one pixel per face of the
    scene (``sqrt(n_faces)`` rounded up to a multiple of 128) within ``AUTO_SIZE``: a
    model of many small faces gets finer views, where its faces and not its pixels are
    most of a view's cost anyway."""
    side = 128 * math.ceil(math.sqrt(scene.n_faces) / 128)
    return int(min(max(side, AUTO_SIZE[0]), AUTO_SIZE[1]))


def decide(scene: SceneLike, views: Any = "auto", size: int | str = "auto", *,
           level: str = "faces", keep_neighbors: int | None = None, min_pixels: int = 1,
           seed: int = 0, max_views: int = AUTO_MAX_VIEWS, client: Any = None,
           progress: bool | None = None, count_on: PartitionedScene | None = None,
           **options) -> Decision:
    """Which faces to keep: :func:`face_visibility` over ``views`` at ``size``, then
    :func:`keep_faces` (``level``, ``keep_neighbors``, ``min_pixels``).

    ``views`` may be or hold ``"auto"``: the given views plus a Fibonacci sphere of
    ``AUTO_FIRST`` outside directions, then rounds of uniformly random outside directions
    (from ``seed``, a stream of their own: never :func:`verify`'s), each of at least
    ``AUTO_ROUND`` views and half as many as all the views before it, until a round
    leaves the kept faces unchanged (``last_round``: that round's views). The stop is a
    sampled test: more views only add to the kept faces, so none of the last round's
    ``m`` random views changed the decision, and a further random view would change it
    with probability below ``3 / m`` (the rule of three, 95% confidence); ``m`` is a
    third of all views, and the work is at most about 2.25 times the views rendered
    until the last change. A round that would pass ``max_views`` is not started
    (``converged`` False, ``last_round`` 0); the first round always runs. With
    ``"auto"``, ``keep_neighbors`` defaults to ``AUTO_RINGS`` (two rings protect faces
    small enough to fall between the pixel centres of every view), else to 0.
    ``size="auto"``: :func:`auto_size`.

    A partitioned scene (:func:`hsr.partition`'s store) is counted sort-last, part by
    part (``count_on``: the store whose whole scene ``scene`` is, when the caller has
    assembled it already); its rings are grown on the assembled scene.

    Raises :class:`VisibilityError` for bad views, size, level, thresholds or
    ``max_views``, and what :func:`face_visibility` raises."""
    from ..scene import views as view_sets

    if isinstance(scene, PartitionedScene):
        count_on, scene = scene, scene.assemble()
    scene = as_scene(scene)
    counted = scene if count_on is None else count_on
    auto, fixed = split_auto(views)
    if keep_neighbors is None:
        keep_neighbors = AUTO_RINGS if auto else 0
    _check_rule(level, keep_neighbors, min_pixels)  # before any view is rendered
    if isinstance(size, str) and size == "auto":
        size = auto_size(scene)
    width, height = check_size(size)
    _check_int("max_views", max_views, 1)
    _check_int("seed", seed, 0)
    run = dict(options, client=client, progress=progress)
    first = fixed + ([f"sphere:{AUTO_FIRST}"] if auto else [])
    cameras = cameras_for(scene, first, width / height, options.get("near"),
                          options.get("far"))
    counts = face_visibility(counted, cameras, (width, height), **run)
    keep = keep_faces(scene, counts, level, keep_neighbors, min_pixels)
    if not auto:
        return Decision(counts, keep, tuple(cameras), (width, height), len(cameras), True)
    rng = np.random.default_rng((AUTO_STREAM, int(seed)))
    bounds = scene.bounds()
    while True:
        more = max(AUTO_ROUND, math.ceil(len(cameras) / 2))
        if len(cameras) + more > max_views:
            return Decision(counts, keep, tuple(cameras), (width, height), 0, False)
        directions = rng.normal(size=(more, 3))
        directions /= np.linalg.norm(directions, axis=1, keepdims=True)
        added = [view_sets.framed(bounds, d, width / height) for d in directions]
        counts = counts + face_visibility(counted, added, (width, height), **run)
        cameras += added
        grown = keep_faces(scene, counts, level, keep_neighbors, min_pixels)
        if np.array_equal(grown, keep):
            return Decision(counts, keep, tuple(cameras), (width, height), more, True)
        keep = grown


def prune(scene: SceneLike, views: Any = "auto", size: int | str = "auto", *, level: str = "faces",
          keep_neighbors: int | None = None, min_pixels: int = 1,
          counts: np.ndarray | None = None, **options) -> tuple:
    """``(pruned Scene, kept)``: ``scene`` without the faces (``level="faces"``) or
    instances (``"objects"``) that no view of ``views`` shows on at least ``min_pixels``
    pixels (summed over the views), ``kept`` the original global ids of the faces left,
    in order (face ``i`` of the pruned scene is face ``kept[i]`` of the original).
    ``keep_neighbors`` K also keeps faces within K edge-rings of a kept face.
    ``views="auto"`` (the default) and ``size="auto"`` choose the views until the
    decision is stable (:func:`decide`, which also takes ``seed``, ``max_views``,
    ``client`` and the render options); a warning says when it did not settle.
    ``counts``: per-face pixel counts already measured (then no view is rendered). A
    partitioned scene is counted part by part and assembled to be cut (see
    :func:`decide`).

    Raises :class:`VisibilityError` for a bad level, threshold or ring count, or when
    nothing is visible (an empty scene is not a scene)."""
    if isinstance(scene, PartitionedScene):
        options = dict(options, count_on=scene)
        scene = scene.assemble()
    scene = as_scene(scene)
    if counts is not None:
        if keep_neighbors is None:
            keep_neighbors = AUTO_RINGS if split_auto(views)[0] else 0
        keep = keep_faces(scene, counts, level, keep_neighbors, min_pixels)
    else:
        decision = decide(scene, views, size, level=level, keep_neighbors=keep_neighbors,
                          min_pixels=min_pixels, **options)
        if not decision.converged:
            warnings.warn(unsettled(decision), VisibilityWarning, stacklevel=2)
        keep = decision.keep
    return subset_scene(scene, keep), np.flatnonzero(keep)


def split_auto(views) -> tuple:
    """``(auto, fixed)``: whether ``views`` is or holds ``"auto"``, and the other views."""
    items = list(views) if isinstance(views, (list, tuple)) else [views]
    fixed = [v for v in items if not (isinstance(v, str) and v == "auto")]
    return len(fixed) < len(items), fixed


def unsettled(decision: Decision) -> str:
    """The one-line message of a decision that did not settle."""
    return (f"no round of new views confirmed the kept faces within max_views "
            f"({decision.views} views rendered); raise max_views or size, keep more "
            f"rings, and measure with verify")


def keep_faces(scene: Scene, counts: ArrayLike, level: str = "faces", keep_neighbors: int = 0,
               min_pixels: int = 1) -> np.ndarray:
    """(n_faces,) bool: the faces to keep, from per-face pixel ``counts`` (or exact areas,
    float: then every face with a visible area is kept, or with ``min_pixels`` above 1
    those with at least that many px^2)."""
    _check_rule(level, keep_neighbors, min_pixels)
    counts = np.asarray(counts)
    if counts.shape != (scene.n_faces,):
        raise VisibilityError(f"counts must have shape ({scene.n_faces},), got {counts.shape}")
    offsets = scene.face_offsets()
    # Exact areas (float): any visible area keeps a face unless a larger threshold (in
    # px^2) is asked for, so that a face under a pixel is never removed.
    exact = np.issubdtype(counts.dtype, np.floating)
    if level == "objects":
        sums = per_object(scene, counts)
        seen = (sums > 0) if exact and min_pixels == 1 else sums >= min_pixels
        keep = np.repeat(seen, np.diff(offsets))
    else:
        keep = (counts > 0) if exact and min_pixels == 1 else counts >= min_pixels
        if keep_neighbors:
            for k, inst in enumerate(scene.instances):
                part = slice(offsets[k], offsets[k + 1])
                keep[part] = grow_rings(inst.mesh, keep[part], keep_neighbors)
    if not keep.any():
        raise VisibilityError("no face is visible from these views (check the cameras "
                              "and --min-pixels): nothing would be left")
    return keep


def _check_rule(level, keep_neighbors, min_pixels) -> None:
    """Refuse a bad level, ring count or pixel threshold (:class:`VisibilityError`)."""
    if level not in LEVELS:
        raise VisibilityError(f"level must be one of {', '.join(LEVELS)}, got {level!r}")
    _check_int("min_pixels", min_pixels, 1, 1 << 62)
    _check_int("keep_neighbors", keep_neighbors, 0, MAX_RINGS)


# Most random views verify renders (each costs two renders of the whole scene).
MAX_VERIFY = 100_000


def _check_int(name: str, value, low: int, high: int | None = None) -> None:
    """Refuse ``value`` unless it is an integer (not a bool) in ``low..high``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < low \
            or (high is not None and value > high):
        bounds = f"in {low}..{high}" if high is not None else f">= {low}"
        raise VisibilityError(f"{name} must be an integer {bounds}, got {value!r}")


def grow_rings(mesh: Mesh, keep: np.ndarray, rings: int) -> np.ndarray:
    """``keep`` plus every face within ``rings`` edge-steps of a kept face. Faces are
    neighbours when they share an edge between two positions (vertices at the same
    position count as one, so seams split for texture coordinates do not stop the
    growth; an edge shared by more than two faces joins all of them; a collapsed edge,
    both ends at one position, joins nothing)."""
    face, starts = _edge_groups(mesh)
    keep = np.array(keep, dtype=bool)
    if not len(starts):
        return keep
    sizes = np.diff(np.append(starts, len(face)))
    for _ in range(rings):
        # A group of equal edges is reached when any of its faces is kept; every face of
        # a reached group is then kept.
        reached = np.repeat(np.logical_or.reduceat(keep[face], starts), sizes)
        grown = keep.copy()
        grown[face[reached]] = True
        if np.array_equal(grown, keep):
            break
        keep = grown
    return keep


def _edge_groups(mesh: Mesh) -> tuple:
    """``(face, starts)``: the faces of the mesh's edges sorted by edge (an undirected
    pair of welded positions), and where each run of equal edges starts. Kept on the mesh
    while its arrays are the same (ring growth runs once per decision round)."""

    def compute():
        vertex = weld(mesh.positions)[1]
        corners = vertex[mesh.faces]
        a = corners[:, [0, 1, 2]].reshape(-1)
        b = corners[:, [1, 2, 0]].reshape(-1)
        n = int(vertex.max()) + 1 if len(vertex) else 1
        # One integer per undirected edge (both orders give the same key).
        key = np.minimum(a, b).astype(np.int64) * n + np.maximum(a, b)
        edge = np.flatnonzero(a != b)
        order = edge[np.argsort(key[edge], kind="stable")]
        key = key[order]
        starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]]) if len(key) else \
            np.zeros(0, dtype=np.int64)
        return order // 3, starts

    return cached_while_same(mesh, "_edge_groups", (mesh.positions, mesh.faces), compute)


def subset_scene(scene: Scene, keep: np.ndarray) -> Scene:
    """The scene with only the ``keep`` faces, in order: each instance's mesh cut to its
    kept faces (their corner attributes too), unused vertices dropped; an instance with
    no face left is dropped. Instances that shared a mesh and keep the same faces still
    share one."""
    offsets = scene.face_offsets()
    cut = {}
    out = Scene()
    for k, inst in enumerate(scene.instances):
        mine = np.asarray(keep[offsets[k]:offsets[k + 1]], dtype=bool)
        if not mine.any():
            continue
        key = (id(inst.mesh), mine.tobytes())
        if key not in cut:
            cut[key] = inst.mesh if mine.all() else _cut_mesh(inst.mesh, mine)
        out.add(cut[key], inst.model, inst.opacity, inst.name)
    return out


def _cut_mesh(mesh: Mesh, mine: np.ndarray) -> Mesh:
    faces = mesh.faces[mine]
    used, local = np.unique(faces, return_inverse=True)

    def part(array):
        return None if array is None else array[mine]

    return Mesh(mesh.positions[used], local.reshape(faces.shape), part(mesh.corner_uv),
                part(mesh.corner_normals), part(mesh.face_colors), mesh.texture, mesh.name,
                part(mesh.corner_colors))


def verify(original: SceneLike, pruned: SceneLike, kept: ArrayLike, count: int = 100,
           size: int | tuple = 512, *, seed: int = 0,
           algorithm: Algorithm = "zbuffer", threads: int | None = None, **options) -> dict:
    """Render ``count`` random viewpoints from outside the original's bounding sphere
    (directions uniform on the sphere from ``seed``: not the decision's views) of the
    original and the pruned scene, and count the pixels whose visible surface differs
    (the pruned scene's face ids mapped back through ``kept``). Returns ``views``,
    ``changed`` pixels, ``covered`` pixels (either scene shows a face) and ``percent``
    (changed of covered). Nothing is masked: every differing pixel counts."""
    from ..render import render
    from ..scene import views as view_sets

    original, pruned = as_scene(original), as_scene(pruned)
    kept = np.asarray(kept, dtype=np.int64)
    if kept.shape != (pruned.n_faces,):
        raise VisibilityError(f"kept must list the pruned scene's {pruned.n_faces} faces, "
                              f"got shape {kept.shape}")
    _check_int("verify count", count, 0, MAX_VERIFY)
    width, height = check_size(size)
    rng = np.random.default_rng(seed)
    directions = rng.normal(size=(count, 3))
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    bounds = original.bounds()
    changed = covered = 0
    for direction in directions:
        camera = view_sets.framed(bounds, direction, width / height)
        before = render(original, camera, width, height, algorithm=algorithm,
                        threads=threads, color=False, **options).face_id
        after = render(pruned, camera, width, height, algorithm=algorithm, threads=threads,
                       color=False, **options).face_id
        after = np.where(after >= 0, kept[np.maximum(after, 0)], -1)
        changed += int(np.count_nonzero(before != after))
        covered += int(np.count_nonzero((before >= 0) | (after >= 0)))
    return {"views": int(count), "changed": changed, "covered": covered,
            "percent": 100.0 * changed / covered if covered else 0.0}
