"""Removing hidden geometry: keep the faces (or whole instances) that some view sees,
optionally grown by K edge-rings, and build the smaller scene with face order kept.
``verify`` measures what the removal changed from viewpoints the decision did not use.

The decision is only as fine as its samples: a face seen by no pixel centre of any view
is removed even if a sliver of it shows between the samples (``keep_neighbors`` guards
against that; ``verify`` counts it, never hides it).
"""

from __future__ import annotations

import numpy as np

from ..scene.mesh import Mesh, Scene, as_scene
from .count import VisibilityError, check_size, face_visibility, per_object

__all__ = ["prune", "keep_faces", "grow_rings", "subset_scene", "verify", "LEVELS"]

LEVELS = ("faces", "objects")
MAX_RINGS = 1000


def prune(scene, views, size=512, *, level: str = "faces", keep_neighbors: int = 0,
          min_pixels: int = 1, counts: np.ndarray | None = None, **options) -> tuple:
    """``(pruned Scene, kept)``: ``scene`` without the faces (``level="faces"``) or
    instances (``"objects"``) that no view of ``views`` shows on at least ``min_pixels``
    pixels (summed over the views), ``kept`` the original global ids of the faces left,
    in order (face ``i`` of the pruned scene is face ``kept[i]`` of the original).
    ``keep_neighbors`` K also keeps faces within K edge-rings of a kept face.
    ``counts``: per-face pixel counts already measured (else :func:`face_visibility`
    with ``views``, ``size`` and ``options``: algorithm, client, cull, ...).

    Raises :class:`VisibilityError` for a bad level, threshold or ring count, or when
    nothing is visible (an empty scene is not a scene)."""
    scene = as_scene(scene)
    if level not in LEVELS:
        raise VisibilityError(f"level must be one of {', '.join(LEVELS)}, got {level!r}")
    if counts is None:
        counts = face_visibility(scene, views, size, **options)
    keep = keep_faces(scene, counts, level, keep_neighbors, min_pixels)
    return subset_scene(scene, keep), np.flatnonzero(keep)


def keep_faces(scene: Scene, counts, level: str = "faces", keep_neighbors: int = 0,
               min_pixels: int = 1) -> np.ndarray:
    """(n_faces,) bool: the faces to keep, from per-face pixel ``counts``."""
    for name, value, top in (("min_pixels", min_pixels, 1 << 62),
                             ("keep_neighbors", keep_neighbors, MAX_RINGS)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) \
                or not (0 if name == "keep_neighbors" else 1) <= value <= top:
            raise VisibilityError(f"{name} must be an integer in "
                                  f"{0 if name == 'keep_neighbors' else 1}..{top}, "
                                  f"got {value!r}")
    counts = np.asarray(counts)
    if counts.shape != (scene.n_faces,):
        raise VisibilityError(f"counts must have shape ({scene.n_faces},), got {counts.shape}")
    offsets = scene.face_offsets()
    if level == "objects":
        seen = per_object(scene, counts) >= min_pixels
        keep = np.repeat(seen, np.diff(offsets))
    else:
        keep = counts >= min_pixels
        if keep_neighbors:
            for k, inst in enumerate(scene.instances):
                part = slice(offsets[k], offsets[k + 1])
                keep[part] = grow_rings(inst.mesh, keep[part], keep_neighbors)
    if not keep.any():
        raise VisibilityError("no face is visible from these views (check the cameras "
                              "and --min-pixels): nothing would be left")
    return keep


def grow_rings(mesh: Mesh, keep: np.ndarray, rings: int) -> np.ndarray:
    """``keep`` plus every face within ``rings`` edge-steps of a kept face. Faces are
    neighbours when they share an edge between two positions (vertices at the same
    position count as one, so seams split for texture coordinates do not stop the
    growth; an edge shared by more than two faces joins all of them)."""
    _, vertex = np.unique(mesh.positions, axis=0, return_inverse=True)
    corners = vertex.reshape(-1)[mesh.faces]
    a = corners[:, [0, 1, 2]].reshape(-1)
    b = corners[:, [1, 2, 0]].reshape(-1)
    # One integer per undirected edge (both orders give the same key).
    n = int(vertex.max()) + 1
    edge = (np.minimum(a, b).astype(np.int64) * n + np.maximum(a, b)).reshape(-1, 3)
    keep = keep.copy()
    for _ in range(rings):
        reached = np.isin(edge, edge[keep]).any(axis=1)
        if (reached == keep).all():
            break
        keep = reached | keep
    return keep


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


def verify(original, pruned, kept, count: int = 100, size=512, *, seed: int = 0,
           algorithm: str = "zbuffer", threads: int | None = None, **options) -> dict:
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
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 0:
        raise VisibilityError(f"verify count must be a non-negative integer, got {count!r}")
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
