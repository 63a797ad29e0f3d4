"""Transparency by painter's order (seed 003): opaque objects first, with depth writes;
then the transparent objects sorted back to front by the eye-space depth of their
bounding-box centre, drawn with the depth test on and the depth mask off, each fragment
blended as ``glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA)`` into an 8-bit colour
buffer (rounded after every blend, as the framebuffer stores it).

Where it is wrong: sorting whole objects cannot order fragments of objects that
interpenetrate or overlap cyclically, nor the faces inside one object (they blend in
submission order). ``transparent_pass(..., order="exact")`` (``render(...,
transparency="exact")``) sorts every fragment per pixel instead (an A-buffer, Carpenter
1984): the correct result, against which the error is measured.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..errors import check_choice
from ..geometry.setup import HALF as _HALF
from ..geometry.setup import ONE as _ONE
from ..geometry.setup import depth_bounds, setup_triangles
from ..raster.fill import depth_passes

__all__ = ["ORDERS", "check_order", "transparent_mask", "fragment_stream", "blend_in_order",
           "object_order", "transparent_pass"]

ORDERS = ("object", "exact")


def check_order(order: str) -> None:
    """``render(transparency=...)``: per-object sorting or the exact per-fragment sort."""
    check_choice(order, ORDERS, "transparency")


def transparent_mask(scene) -> np.ndarray:
    """(instances,) bool: the instances drawn blended (opacity < 1)."""
    return np.array([inst.opacity < 1.0 for inst in scene.instances])


@njit(cache=True, nogil=True)
def _stream(vert_fixed, edge_bias, bbox, zplane, tri_face, width, height, depth_test,
            depth_func, z_lo, z_hi, depth_buf, out_pixel, out_face, out_depth, count_only):
    """Every fragment of the triangles, in submission order, that passes the depth test
    against ``depth_buf`` (read only). With ``count_only`` just counts them."""
    k = 0
    for t in range(bbox.shape[0]):
        x0, x1, y0, y1 = bbox[t, 0], bbox[t, 1], bbox[t, 2], bbox[t, 3]
        if x0 > x1 or y0 > y1:
            continue
        X0, Y0 = np.int64(vert_fixed[t, 0]), np.int64(vert_fixed[t, 1])
        X1, Y1 = np.int64(vert_fixed[t, 2]), np.int64(vert_fixed[t, 3])
        X2, Y2 = np.int64(vert_fixed[t, 4]), np.int64(vert_fixed[t, 5])
        z_min, z_max = depth_bounds(zplane, t, z_lo, z_hi)
        for j in range(y0, y1 + 1):
            py = np.int64(j) * _ONE + _HALF
            row = height - 1 - j
            z_row = zplane[t, 2] + zplane[t, 4] * (j + 0.5 - zplane[t, 1])
            for i in range(x0, x1 + 1):
                px = np.int64(i) * _ONE + _HALF
                e0 = (X1 - X0) * (py - Y0) - (Y1 - Y0) * (px - X0) + edge_bias[t, 0]
                e1 = (X2 - X1) * (py - Y1) - (Y2 - Y1) * (px - X1) + edge_bias[t, 1]
                e2 = (X0 - X2) * (py - Y2) - (Y0 - Y2) * (px - X2) + edge_bias[t, 2]
                if (e0 | e1 | e2) < 0:
                    continue
                z = np.float32(min(max(z_row + zplane[t, 3] * (i + 0.5 - zplane[t, 0]),
                                       z_min), z_max))
                if depth_test and not depth_passes(depth_func, z, depth_buf[row, i]):
                    continue
                if not count_only:
                    out_pixel[k] = row * width + i
                    out_face[k] = tri_face[t]
                    out_depth[k] = z
                k += 1
    return k


def fragment_stream(screen, depth_buf, state, workers):
    """(pixel index row * W + col, face id, window depth) of every fragment of ``screen``'s
    triangles that passes ``state``'s depth test against ``depth_buf``, in submission
    order (the order OpenGL blends them)."""
    width, height = screen.width, screen.height
    vert_fixed, edge_bias, bbox, zplane, _ = setup_triangles(
        np.ascontiguousarray(screen.xy_window), np.ascontiguousarray(screen.depth_window),
        width, height, workers, state.polygon_offset)
    z_lo, z_hi = min(state.depth_range), max(state.depth_range)
    args = (vert_fixed, edge_bias, bbox, zplane, screen.face_id, width, height,
            state.depth_test, state.depth_func.code, z_lo, z_hi, depth_buf)
    empty = np.zeros(0, np.int64)
    n = _stream(*args, empty, empty, np.zeros(0, np.float32), True)
    pixel, face, depth = np.empty(n, np.int64), np.empty(n, np.int64), np.empty(n, np.float32)
    _stream(*args, pixel, face, depth, False)
    return pixel, face, depth


@njit(cache=True, nogil=True)
def blend_in_order(image_flat, pixel, rgb, alpha):
    """``dst = alpha * src + (1 - alpha) * dst`` for each fragment in order, rounding to
    8 bits after each blend. ``image_flat`` is (H*W, 3) uint8."""
    for k in range(pixel.shape[0]):
        p = pixel[k]
        for c in range(3):
            value = alpha[k] * rgb[k, c] + (1.0 - alpha[k]) * image_flat[p, c]
            image_flat[p, c] = np.uint8(min(max(math.floor(value + 0.5), 0.0), 255.0))


def object_order(scene, camera, instances) -> list:
    """Instances sorted back to front by the eye-space depth of their world bounding-box
    centre (painter's order per object); ties keep submission order."""
    view = camera.view_matrix
    keys = []
    for k in instances:
        inst = scene.instances[k]
        tri = inst.mesh.positions[inst.mesh.faces]
        lo, hi = tri.reshape(-1, 3).min(axis=0), tri.reshape(-1, 3).max(axis=0)
        centre = inst.model[:3, :3] @ (0.5 * (lo + hi)) + inst.model[:3, 3]
        keys.append(float(view[2, :3] @ centre + view[2, 3]))  # z_eye: more negative = farther
    return [instances[i] for i in np.argsort(keys, kind="stable")]


def transparent_pass(ctx, screen, depth_buf, state, image, order="object"):
    """Blend the transparent instances over ``image`` (H, W, 3 uint8, modified).

    ``order="object"``: painter's order per object (what OpenGL programs do);
    ``"exact"``: every fragment sorted per pixel (see :func:`exact_blend`).
    Returns stats."""
    scene = ctx.scene
    width = screen.width
    transparent = [k for k, inst in enumerate(scene.instances) if inst.opacity < 1.0]
    owner = scene.instance_of(screen.face_id)
    flat = image.reshape(-1, 3)
    total = 0
    if order == "exact":
        sub = screen.subset(np.isin(owner, transparent))
        pixel, face, depth = fragment_stream(sub, depth_buf, state, ctx.workers)
        # Far to near per pixel; equal depths keep submission order.
        far_first = -depth if state.depth_range[1] >= state.depth_range[0] else depth
        sort = np.lexsort((np.arange(len(pixel)), far_first, pixel))
        pixel, face, depth = pixel[sort], face[sort], depth[sort]
        total = _shade_and_blend(ctx, scene, flat, pixel, face, depth, width)
    else:
        for k in object_order(scene, ctx.camera, transparent):
            sub = screen.subset(owner == k)
            pixel, face, depth = fragment_stream(sub, depth_buf, state, ctx.workers)
            total += _shade_and_blend(ctx, scene, flat, pixel, face, depth, width)
    return {"transparent_objects": len(transparent), "transparent_fragments": int(total),
            "transparency_order": order}


def _shade_and_blend(ctx, scene, flat, pixel, face, depth, width):
    from .shading import shade_fragments

    if len(pixel) == 0:
        return 0
    rgb = shade_fragments(ctx, pixel // width, pixel % width, face, depth)
    alpha = np.array([inst.opacity for inst in scene.instances])[scene.instance_of(face)]
    blend_in_order(flat, pixel, rgb, alpha)
    return len(pixel)
