"""The ray/triangle test and who owns a hit on a shared edge.

Intersection is the watertight test of Woop, Benthin & Wald (2013): the ray is made the
+z axis by a permutation and a shear (:func:`ray_frame`, :func:`sheared_corners`), and the
three 2-D edge functions are evaluated so that an edge shared by two triangles gives
exactly opposite values in both, so no ray slips between them (:func:`intersect`).

A ray exactly on a shared edge or vertex meets every triangle there; the nearest-hit and
any-hit queries keep that (a hit is a hit), but counting must see the surface once, so
:func:`owns` breaks the tie as a rasterizer's top-left rule does: on a zero edge value,
the triangle owns the point only when that edge, in the ray's own 2-D frame and with the
triangle's winding made counter-clockwise there, points one way (up, or right when
level). The neighbour across the edge walks it the other way, so exactly one of the two
owns it; at a vertex, exactly one triangle of a fan around it. A ray that grazes a
silhouette edge meets two triangles of opposite facing, which then walk the edge the same
way: both or neither count, and parity is kept."""

from __future__ import annotations

import numpy as np
from numba import njit

from .layout import corner

__all__ = ["ray_frame", "face_normal", "sheared_corners", "culled", "intersect", "owns"]


@njit(cache=True, nogil=True, inline="always")
def ray_frame(ox, oy, oz, dx, dy, dz):
    """The ray's frame for :func:`intersect` (Woop, Benthin & Wald 2013): kz the axis
    of the direction's largest component, kx and ky the others (swapped when that
    component is negative, which keeps the winding), the shear (sx, sy, sz) that makes
    the ray the +z axis, and the origin's coordinates on the permuted axes."""
    ad = (abs(dx), abs(dy), abs(dz))
    kz = 0
    if ad[1] > ad[kz]:
        kz = 1
    if ad[2] > ad[kz]:
        kz = 2
    kx, ky = (kz + 1) % 3, (kz + 2) % 3
    dk = (dx, dy, dz)
    if dk[kz] < 0.0:
        kx, ky = ky, kx
    sz = 1.0 / dk[kz]
    sx, sy = dk[kx] * sz, dk[ky] * sz
    ok = (ox, oy, oz)
    return kx, ky, kz, sx, sy, sz, ok[kx], ok[ky], ok[kz]


@njit(cache=True, nogil=True, inline="always")
def face_normal(tris, f):
    """Triangle ``f``'s normal as wound, (B - A) x (C - A), not normalised; in float64
    whether the corners are stored in float32 or float64 (float32 arithmetic would
    round it differently). ``tris``: the walks' corners, rows or blocks
    (:func:`hsr.algorithms.bvh.layout.corner`)."""
    p0x = np.float64(corner(tris, f, 0, 0))
    p0y = np.float64(corner(tris, f, 0, 1))
    p0z = np.float64(corner(tris, f, 0, 2))
    e1x, e1y, e1z = (corner(tris, f, 1, 0) - p0x, corner(tris, f, 1, 1) - p0y,
                     corner(tris, f, 1, 2) - p0z)
    e2x, e2y, e2z = (corner(tris, f, 2, 0) - p0x, corner(tris, f, 2, 1) - p0y,
                     corner(tris, f, 2, 2) - p0z)
    return e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x


@njit(cache=True, nogil=True, inline="always")
def sheared_corners(tris, f, okx, oky, okz, kx, ky, kz, sx, sy):
    """Triangle ``f``'s corners relative to the ray's origin on the permuted axes, sheared
    so the ray is the +z axis (Woop et al.): (ax, ay, az, bx, by, bz, cx, cy, cz). One
    function for every test that must see the same numbers (the hit test and the
    ownership of an edge hit)."""
    az = corner(tris, f, 0, kz) - okz
    bz = corner(tris, f, 1, kz) - okz
    cz = corner(tris, f, 2, kz) - okz
    ax = corner(tris, f, 0, kx) - okx - sx * az
    ay = corner(tris, f, 0, ky) - oky - sy * az
    bx = corner(tris, f, 1, kx) - okx - sx * bz
    by = corner(tris, f, 1, ky) - oky - sy * bz
    cx = corner(tris, f, 2, kx) - okx - sx * cz
    cy = corner(tris, f, 2, ky) - oky - sy * cz
    return ax, ay, az, bx, by, bz, cx, cy, cz


@njit(cache=True, nogil=True, inline="always")
def culled(tris, f, cull_code, front_ccw, dx, dy, dz):
    """Whether glCullFace's ``cull_code`` (1 back, 2 front, 3 both; 0 none) drops
    triangle ``f`` for a ray of direction (dx, dy, dz): the ray meets the
    counter-clockwise (front, when ``front_ccw``) side when the normal opposes it."""
    nx, ny, nz = face_normal(tris, f)
    facing = nx * dx + ny * dy + nz * dz
    front = (facing < 0.0) == front_ccw
    return (cull_code == 1 and not front) or (cull_code == 2 and front) or cull_code == 3


@njit(cache=True, nogil=True, inline="always")
def intersect(tris, f, okx, oky, okz, kx, ky, kz, sx, sy, sz, cull_code, front_ccw, dx, dy,
               dz):
    """Woop-Benthin-Wald watertight ray/triangle test (``ok*`` are the ray origin's
    coordinates on the permuted axes). Returns (t, u, v, w) with t = -1 for a miss;
    (u, v, w) are barycentrics of corners (0, 1, 2)."""
    ax, ay, az, bx, by, bz, cx, cy, cz = sheared_corners(tris, f, okx, oky, okz, kx, ky,
                                                         kz, sx, sy)
    # 2-D edge functions; the same edge in a neighbour gives exactly the opposite value.
    u = cx * by - cy * bx
    v = ax * cy - ay * cx
    w = bx * ay - by * ax
    det = u + v + w
    # Outside when the edge values have mixed signs. One test of bitwise ands and ors,
    # not short-circuit ones: each of those is a branch, and on incoherent rays their
    # outcomes are coin flips.
    if (((u < 0.0) | (v < 0.0) | (w < 0.0)) & ((u > 0.0) | (v > 0.0) | (w > 0.0))) | (
            det == 0.0):
        return -1.0, 0.0, 0.0, 0.0
    if cull_code != 0 and culled(tris, f, cull_code, front_ccw, dx, dy, dz):
        return -1.0, 0.0, 0.0, 0.0
    t = (u * (sz * az) + v * (sz * bz) + w * (sz * cz)) / det
    return t, u / det, v / det, w / det


@njit(cache=True, nogil=True, inline="always")
def _edge_owned(px, py, qx, qy, flip):
    """Whether the triangle owns the points on its edge P -> Q: walked counter-clockwise
    in the ray's 2-D frame (Q -> P when ``flip``, the triangle being wound the other way
    there), the edge goes up, or right when level."""
    if flip:
        px, py, qx, qy = qx, qy, px, py
    return qy > py or (qy == py and qx > px)


@njit(cache=True, nogil=True)
def owns(tris, f, okx, oky, okz, kx, ky, kz, sx, sy):
    """With one or two zero edge values (the ray through an edge or a vertex of
    triangle ``f``): whether ``f`` counts the hit (see the module notes). The corners
    are :func:`hsr.algorithms.bvh.triangle.sheared_corners`, as the hit test saw them, so the
    zero tests see the same numbers."""
    ax, ay, _, bx, by, _, cx, cy, _ = sheared_corners(tris, f, okx, oky, okz, kx, ky, kz,
                                                      sx, sy)
    u = cx * by - cy * bx  # edge B -> C
    v = ax * cy - ay * cx  # edge C -> A
    w = bx * ay - by * ax  # edge A -> B
    flip = u + v + w < 0.0
    return not ((u == 0.0 and not _edge_owned(bx, by, cx, cy, flip))
                or (v == 0.0 and not _edge_owned(cx, cy, ax, ay, flip))
                or (w == 0.0 and not _edge_owned(ax, ay, bx, by, flip)))
