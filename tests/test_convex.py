"""The convex-polygon helpers of the exact regions against independent answers: the
separating-axis test against shapely's intersection area, and the side test against the
clip it lets the regions skip."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hsr.geometry.convex import MAX_VERTICES, clip_half_plane, side_of_line, triangles_apart

shapely = pytest.importorskip("shapely")

# Small integer grids make shared corners, shared edges and touching lines common.
coord = st.integers(-4, 4).map(float)
triangle = st.lists(st.tuples(coord, coord), min_size=3, max_size=3).map(np.array).filter(
    lambda t: (t[1, 0] - t[0, 0]) * (t[2, 1] - t[0, 1])
    != (t[2, 0] - t[0, 0]) * (t[1, 1] - t[0, 1]))


@settings(max_examples=400, deadline=None)
@given(triangle, triangle)
def test_triangles_apart_is_no_common_area(t, u):
    area = shapely.Polygon(t).intersection(shapely.Polygon(u)).area
    # Separating axes decide exactly for triangles: apart <=> no common area.
    assert triangles_apart(t, u) == (area == 0.0)
    assert triangles_apart(u, t) == triangles_apart(t, u)


def _buffer(poly):
    out = np.zeros((MAX_VERTICES, 2))
    out[:len(poly)] = poly
    return out


@settings(max_examples=400, deadline=None)
@given(triangle, coord, coord, coord)
def test_a_polygon_on_one_side_is_what_the_clip_keeps_whole_or_drops(t, a, b, c):
    if a == 0.0 and b == 0.0:
        return
    src, dst = _buffer(t), np.zeros((MAX_VERTICES, 2))
    side = side_of_line(src, 3, a, b, c)
    kept = clip_half_plane(src, 3, a, b, c, dst)
    dropped = clip_half_plane(src, 3, -a, -b, -c, np.zeros((MAX_VERTICES, 2)))
    d = t @ np.array([a, b]) + c
    assert side == (1 if d.min() > 0 else -1 if d.max() < 0 else 0)
    if side > 0:  # kept whole, vertex for vertex; nothing on the other side
        assert kept == 3 and np.array_equal(dst[:3], t) and dropped == 0
    elif side < 0:
        assert kept == 0 and dropped == 3
