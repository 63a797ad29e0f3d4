"""geometry.merge: a face's convex pieces merged into rings cover exactly what the pieces
cover (shapely's union as the reference), with fewer rings where pieces share edges."""

import numpy as np
import pytest

import hsr
from conftest import require
from hsr.geometry.merge import merge_pieces

shapely = require("shapely")


@pytest.mark.parametrize("name", ["spheres", "penetration", "cyclic"])
def test_merged_rings_cover_what_the_pieces_cover(name):
    scene, camera = hsr.scenes.get(name)
    regions = hsr.visible_regions(scene, camera, 256, 192)
    order = np.argsort(regions.piece_row, kind="stable")
    size = np.diff(regions.piece_start)[order]
    start = np.r_[0, np.cumsum(size)]
    src = np.repeat(regions.piece_start[:-1][order] - start[:-1], size) + np.arange(start[-1])
    verts = regions.vertices[src]
    rows = regions.piece_row[order]
    groups = np.flatnonzero(np.r_[True, rows[1:] != rows[:-1], True])
    ring_xy, ring_start, group_ring = merge_pieces(verts, start, groups)
    assert len(ring_start) - 1 <= len(regions.piece_row)
    reference = regions.polygons  # shapely's snap-rounded union of each face's pieces
    for g in range(len(groups) - 1):
        rings = [ring_xy[ring_start[r]:ring_start[r + 1]]
                 for r in range(group_ring[g], group_ring[g + 1])]
        signs = [np.sign(np.sum(r[:, 0] * np.roll(r[:, 1], -1) - np.roll(r[:, 0], -1) * r[:, 1]))
                 for r in rings]
        # What a nonzero-winding fill covers: the rings wound one way minus the holes.
        outer = shapely.union_all([shapely.Polygon(r).buffer(0)
                                   for r, sg in zip(rings, signs) if sg == signs[0]])
        holes = shapely.union_all([shapely.Polygon(r).buffer(0)
                                   for r, sg in zip(rings, signs) if sg != signs[0]])
        covered = shapely.difference(outer, holes)
        expected = reference[rows[groups[g]]]
        # Merged vertices sit on the 2^-20 px grid: each moves at most 2^-21 px.
        assert shapely.symmetric_difference(covered, expected).area <= \
            2.0**-20 * expected.length + 1e-12
    merged_groups = np.diff(group_ring) < np.diff(groups)
    assert merged_groups.any()
