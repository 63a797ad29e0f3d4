"""The independent truth: a brute-force per-pixel ray test in plain NumPy.

For every pixel centre it builds the ray from the near plane to the far plane by
un-projecting through the inverse view-projection matrix, intersects it with every world-
space triangle (Moller-Trumbore), decides facing from the triangle normal against the ray,
converts the hit point to window depth through the projection, and runs OpenGL's per-
fragment depth test in submission order. It shares no code with hsr's pipeline or
rasterizer: no clipping, no snapping, no edge functions, no plane interpolation.
"""

from __future__ import annotations

import numpy as np

_FUNCS = {
    "never": lambda z, s, e: np.zeros(z.shape, bool),
    "less": lambda z, s, e: z < s - e,
    "equal": lambda z, s, e: np.abs(z - s) <= e,
    "lequal": lambda z, s, e: z <= s + e,
    "greater": lambda z, s, e: z > s + e,
    "notequal": lambda z, s, e: np.abs(z - s) > e,
    "gequal": lambda z, s, e: z >= s - e,
    "always": lambda z, s, e: np.ones(z.shape, bool),
}


def world_triangles(scene) -> np.ndarray:
    """(F, 3, 3) world-space corners, computed here rather than trusted from hsr."""
    if not hasattr(scene, "instances"):  # a bare Mesh
        scene = type("OneMesh", (), {"instances": [type("I", (), {
            "mesh": scene, "model": np.eye(4)})]})
    parts = []
    for inst in scene.instances:
        p = np.c_[inst.mesh.positions, np.ones(len(inst.mesh.positions))] @ inst.model.T
        parts.append(p[:, :3][inst.mesh.faces])
    return np.concatenate(parts)


def reference_render(scene, camera, width, height, *, depth_test=True, depth_func="less",
                     depth_mask=True, clear_depth=1.0, depth_range=(0.0, 1.0), cull="none",
                     front_face="ccw", jitter=(0.0, 0.0), depth_buffer=None, tie_eps=1.2e-7,
                     with_barycentrics=False):
    """Returns ``(face_id (H, W) int32, depth (H, W) float64)``, row 0 = top.

    ``jitter`` moves every sample point by that many pixels (to find pixels whose centre
    lies on an edge). ``depth_buffer`` starts the depth buffer from an earlier draw.
    Fragment depths are rounded to float32 (the buffer format) and depths within
    ``tie_eps`` (about two float32 steps at 1.0) compare as equal: the rasterizer computes
    them in a different order, so exact float ties are not comparable across
    implementations.
    """
    tris = world_triangles(scene)
    view_proj = camera.projection_matrix(width / height) @ camera.view_matrix
    inv = np.linalg.inv(view_proj)
    xs = (np.arange(width) + 0.5 + jitter[0]) / width * 2.0 - 1.0
    ys = 1.0 - (np.arange(height) + 0.5 + jitter[1]) / height * 2.0
    gx, gy = np.meshgrid(xs, ys)
    ndc = np.stack([gx.ravel(), gy.ravel()], axis=1)
    ones = np.ones(len(ndc))
    near_h = np.c_[ndc, -ones, ones] @ inv.T
    far_h = np.c_[ndc, ones, ones] @ inv.T
    origin = near_h[:, :3] / near_h[:, 3:]
    direction = far_h[:, :3] / far_h[:, 3:] - origin  # t in [0, 1] spans near..far

    n_pix = len(origin)
    face = np.full(n_pix, -1, dtype=np.int32)
    if depth_buffer is None:
        depth = np.full(n_pix, float(clear_depth))
    else:
        depth = np.asarray(depth_buffer, dtype=np.float64).ravel().copy()
    bary = np.zeros((n_pix, 3))
    d_near, d_far = depth_range
    test = _FUNCS[depth_func]
    for f, (v0, v1, v2) in enumerate(tris):
        e1, e2 = v1 - v0, v2 - v0
        normal = np.cross(e1, e2)
        if not np.any(normal):
            continue
        pvec = np.cross(direction, e2)
        det = pvec @ e1
        ok = np.abs(det) > 1e-300
        inv_det = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        tvec = origin - v0
        u = np.einsum("ij,ij->i", tvec, pvec) * inv_det
        qvec = np.cross(tvec, e1)
        v = np.einsum("ij,ij->i", direction, qvec) * inv_det
        t = (qvec @ e2) * inv_det
        hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t >= 0) & (t <= 1)
        # Front-facing = counter-clockwise on screen = the ray meets the normal's side.
        ccw = direction @ normal < 0
        front = ccw if front_face == "ccw" else ~ccw
        if cull == "back":
            hit &= front
        elif cull == "front":
            hit &= ~front
        elif cull == "front_and_back":
            hit &= False
        if not hit.any():
            continue
        idx = np.flatnonzero(hit)
        p = origin[idx] + t[idx, None] * direction[idx]
        clip = np.c_[p, np.ones(len(p))] @ view_proj.T
        z = clip[:, 2] / clip[:, 3] * 0.5 * (d_far - d_near) + 0.5 * (d_far + d_near)
        z = np.clip(z, min(d_near, d_far), max(d_near, d_far)).astype(np.float32)
        z = z.astype(np.float64)
        passed = test(z, depth[idx], tie_eps) if depth_test else np.ones(len(idx), bool)
        win = idx[passed]
        face[win] = f
        bary[win] = np.c_[1 - u[win] - v[win], u[win], v[win]]
        if depth_test and depth_mask:
            depth[win] = z[passed]
    if with_barycentrics:
        return face.reshape(height, width), depth.reshape(height, width), bary.reshape(
            height, width, 3)
    return face.reshape(height, width), depth.reshape(height, width)


def ambiguous_pixels(scene, camera, width, height, delta=0.01, **state) -> np.ndarray:
    """(H, W) bool: pixels whose face id changes when the sample point moves by
    ``delta`` pixels diagonally: their centre lies (within delta) on an edge or on the
    intersection line of two surfaces, where either answer is right."""
    base, _ = reference_render(scene, camera, width, height, **state)
    amb = np.zeros(base.shape, bool)
    for jx, jy in ((delta, delta), (-delta, delta), (delta, -delta), (-delta, -delta)):
        other, _ = reference_render(scene, camera, width, height, jitter=(jx, jy), **state)
        amb |= other != base
    return amb


def compare(frame_face, frame_depth, ref_face, ref_depth, ambiguous, depth_tol=2e-6):
    """Mismatch counts outside the ambiguous pixels: (face mismatches, depth mismatches,
    pixels compared)."""
    sure = ~ambiguous
    face_bad = (frame_face != ref_face) & sure
    same = (frame_face == ref_face) & sure & (ref_face >= 0)
    depth_bad = same & (np.abs(frame_depth.astype(np.float64) - ref_depth) > depth_tol)
    return int(face_bad.sum()), int(depth_bad.sum()), int(sure.sum())


def moller_trumbore(o, d, a, e1, e2, min_det=0.0):
    """One ray (origin ``o``, direction ``d``) against every triangle (corner ``a``, edges
    ``e1``, ``e2``), Moller-Trumbore in float64: ``(ok, u, v, t)`` per triangle, ``ok``
    false where ``|det|`` is not above ``min_det`` (0: the ray in the triangle's plane)."""
    p = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, p)
    ok = np.abs(det) > min_det
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = o - a
    u = np.einsum("ij,ij->i", s, p) * inv
    q = np.cross(s, e1)
    v = (q @ d) * inv
    t = np.einsum("ij,ij->i", e2, q) * inv
    return ok, u, v, t


def occluded(scene, camera, points, rel_eps=1e-7) -> np.ndarray:
    """(P,) bool: is anything strictly between the eye and each world-space point?
    Moller-Trumbore of the segment eye -> point against every triangle; hits within
    ``rel_eps`` of the point (its own faces) do not count. Perspective cameras only."""
    tris = world_triangles(scene)
    eye = np.asarray(camera.eye, dtype=np.float64)
    direction = np.asarray(points, dtype=np.float64) - eye  # t = 1 at the point
    out = np.zeros(len(direction), dtype=bool)
    v0, e1, e2 = tris[:, 0], tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    tvec = eye - v0  # (T, 3)
    qvec = np.cross(tvec, e1)
    for start in range(0, len(direction), 64):
        d = direction[start:start + 64]  # (P, 3)
        pvec = np.cross(d[:, None, :], e2[None])  # (P, T, 3)
        det = np.einsum("ptk,tk->pt", pvec, e1)
        ok = np.abs(det) > 1e-300
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        u = np.einsum("ptk,tk->pt", pvec, tvec) * inv
        v = np.einsum("pk,tk->pt", d, qvec) * inv
        t = np.einsum("tk,tk->t", qvec, e2)[None] * inv
        hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0) & (t < 1 - rel_eps)
        out[start:start + 64] = hit.any(axis=1)
    return out


def unproject(camera, width, height, window_points) -> np.ndarray:
    """World positions of (P, 3) window points (x, y up, depth in [0, 1])."""
    view_proj = camera.projection_matrix(width / height) @ camera.view_matrix
    p = np.asarray(window_points, dtype=np.float64)
    ndc = np.c_[2 * p[:, 0] / width - 1, 2 * p[:, 1] / height - 1, 2 * p[:, 2] - 1,
                np.ones(len(p))]
    world = ndc @ np.linalg.inv(view_proj).T
    return world[:, :3] / world[:, 3:]
