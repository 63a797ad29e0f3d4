"""The binary tree a BVH build goes through, for the tests that check it: hsr keeps only
the 8-wide tree the walks read (:class:`hsr.algorithms.bvh.sah.BVH`), so the tests build
the binary one again here, with the build's own function, and number it afresh."""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import numpy as np

from hsr.algorithms.bvh import sah
from hsr.parallel import Workers
from hsr.scene.mesh import as_scene


def outwards32(values: np.ndarray, towards: float) -> np.ndarray:
    """``values`` in float32, each rounded towards ``towards`` (-inf: down, +inf: up)
    where float32 cannot hold it exactly, as the walked tree's boxes are."""
    with np.errstate(over="ignore"):
        rounded = values.astype(np.float32)
    moved = rounded < values if towards > 0 else rounded > values
    rounded[moved] = np.nextafter(rounded[moved], np.float32(towards))
    return rounded


def build_keeping_tree(scene, threads=None) -> SimpleNamespace:
    """``sah.build(scene, threads)``'s fields and the binary tree it went through:
    node_min, node_max (N, 3) float32 (rounded outwards), node_left (N,) int32 (the first
    child, the second next to it; -1 for a leaf), node_start, node_count (N,) int32 (a
    leaf's slots, numbered as the walked tree's: where the build's leaf order put them,
    moved where the leaves are packed into blocks), n_nodes. The nodes are numbered from
    the root, breadth first, so the numbers the parallel build leaves unused between its
    subtrees are gone."""
    bvh = sah.build(scene, threads)
    positions, faces = sah._world_mesh(as_scene(scene))
    with Workers(threads) as workers:
        lo, hi, left, start, count, order, n_nodes = sah.binary_tree(positions, faces,
                                                                     workers)
    # The same tree the walked one came from; its leaves packed into blocks move the
    # binary leaf order's slot k to moved[k] (the rest, padding, hold face -1).
    moved = _moved_slots(bvh.tri_index, order, len(faces))
    assert np.array_equal(bvh.tri_index[moved], order)
    padding = np.ones(len(bvh.tri_index), dtype=bool)
    padding[moved] = False
    assert (bvh.tri_index[padding] == -1).all()
    old, new_left = [0], []
    for node in old:  # (grows as it goes: breadth first)
        if left[node] >= 0:
            new_left.append(len(old))
            old += [left[node], left[node] + 1]
        else:
            new_left.append(-1)
    assert len(old) == n_nodes
    old = np.array(old)
    fields = {f.name: getattr(bvh, f.name) for f in dataclasses.fields(bvh)}
    return SimpleNamespace(
        **fields, bvh=bvh, n_wide_nodes=bvh.n_wide_nodes, walked=bvh.walked,
        node_min=outwards32(lo[old], -np.inf), node_max=outwards32(hi[old], np.inf),
        node_left=np.array(new_left, dtype=np.int32),
        node_start=np.append(moved, len(bvh.tri_index))[start[old]].astype(np.int32),
        node_count=count[old].astype(np.int32), n_nodes=len(old))


def _moved_slots(tri_index: np.ndarray, order: np.ndarray, n_faces: int) -> np.ndarray:
    """Where each slot of the binary tree's leaf order (its faces ``order``, of
    ``n_faces``) lies in the walked slots ``tri_index`` (each face in one slot; -1 in
    padding slots)."""
    held = np.flatnonzero(tri_index >= 0)
    slot_of_face = np.full(n_faces, -1, dtype=np.int64)
    slot_of_face[tri_index[held]] = held
    return slot_of_face[order]
