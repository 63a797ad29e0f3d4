"""The 8-wide BVH's box test, and the ordering of its lanes, as LLVM vector operations.

Numba leaves the slab test of several boxes scalar however its loop is shaped (checked
with ``inspect_asm``: ``vmulsd``/``vminsd`` on ``xmm``, no ``ymm``), so the walk of
:func:`hsr.algorithms.bvh.walk.trace_range` spent most of a node on one lane at a time.
:func:`box_keys8` writes the slab test on ``<8 x float>`` values through a Numba
intrinsic: eight float32 lanes, one AVX2 register, the node's bounds used as stored; the
ray comes rounded to float32 with a pad that keeps the test conservative
(:func:`hsr.algorithms.bvh.boxes.box_frame`). The packets' test (:func:`packet_keys8`)
keeps the float64 arithmetic of the scalar careful test, each operation once for eight
lanes in the same order and without fused multiply-adds, so every lane's result is bit
for bit the scalar one (``_careful_entry`` without its NaN care). On a CPU with narrower
vectors LLVM splits the operations, and the results do not change. :func:`sort_keys8`
orders a node's entered lanes without branches (the ordered step of
:func:`hsr.algorithms.bvh.walk.trace_range`).

What it exports, by use:

- a node's boxes: :func:`box_keys8` (one ray, entries as sortable keys),
  :func:`box_mask8` (one ray, the mask alone), :func:`record_words` (a node's
  references), :func:`packet_keys8` and
  :func:`packet_keys8_shared` (four rays; four from one origin);
- a leaf's triangles: :func:`leaf_filter4` (one ray, four triangles at once),
  :func:`leaf_test4` (the same with the rest of the test's values) and
  :func:`leaf_filter4_rays` (four rays from one origin);
- ordering and bits: :func:`min_key8`, :func:`sort_keys8`, :func:`lowest_bit`,
  :func:`bit_count`, :func:`float_bits`, :func:`next_float32`;
- the build: :func:`grow_box` (a bin's box grown by a face's);
- memory: :func:`prefetch` (a hint, never a change of result) and :func:`borrowed` (a
  view without reference counts, for the walks' loops).
"""

from __future__ import annotations

import sys

from llvmlite import ir
from numba.core import cgutils, types
from numba.extending import intrinsic

__all__ = ["NODE_BYTES", "box_keys8", "box_mask8", "record_words", "packet_keys8",
           "packet_keys8_shared", "leaf_filter4", "leaf_test4", "leaf_filter4_rays", "min_key8",
           "sort_keys8", "lowest_bit", "bit_count", "float_bits", "next_float32", "grow_box",
           "prefetch", "borrowed"]

_I32 = ir.IntType(32)
_I64 = ir.IntType(64)
_D4 = ir.VectorType(ir.DoubleType(), 4)
_F8 = ir.VectorType(ir.FloatType(), 8)
_D8 = ir.VectorType(ir.DoubleType(), 8)
_L8 = ir.VectorType(_I64, 8)
_K8 = ir.VectorType(_I32, 8)

# The bytes of a wide node record (hsr.algorithms.bvh.layout.NODE_WORDS 32-bit words;
# tests/test_rays.py::test_node_records_are_read_where_they_are_written checks the two
# agree).
NODE_BYTES = 256


def _splat(builder, x, width=4):
    """A value (float64 or float32) in all ``width`` lanes."""
    vector = ir.VectorType(x.type, width)
    v = builder.insert_element(ir.Constant(vector, ir.Undefined), x, ir.Constant(_I32, 0))
    return builder.shuffle_vector(v, ir.Constant(vector, ir.Undefined),
                                  ir.Constant(ir.VectorType(_I32, width), [0] * width))


def _min(builder, x, y):
    """``x if x < y else y`` per lane: Numba's ``min`` of two floats."""
    return builder.select(builder.fcmp_ordered("<", x, y), x, y)


def _max(builder, x, y):
    """``x if x > y else y`` per lane: Numba's ``max`` of two floats."""
    return builder.select(builder.fcmp_ordered(">", x, y), x, y)


def _i64(value):
    return ir.Constant(ir.IntType(64), value)


def _row_pointer(context, builder, array_type, array, row, element=None):
    """A pointer to the start of row ``row`` of a 2-D array, to ``element`` (default
    float, for float32 arrays)."""
    ary = context.make_array(array_type)(context, builder, array)
    stride = cgutils.unpack_tuple(builder, ary.strides, 2)[0]
    raw = builder.bitcast(ary.data, ir.IntType(8).as_pointer())
    return builder.bitcast(builder.gep(raw, [builder.mul(row, stride)]),
                           (element or ir.FloatType()).as_pointer())


# The slack that keeps the slab test conservative (never missing a box the exact ray
# meets; Ize 2013's argument): a computed distance (p - o) * inv is three roundings
# (u = 2**-53 each) from the exact one, so t_in may be a factor (1 + u)^3 above its
# exact value and t_out (1 - u)^3 below; the slack's own multiply and add round twice
# more, and (1 + u)^3 <= (1 - u)^5 SLACK needs SLACK >= 1 + 8u (1 + 10u here). SLACK_ABS
# covers distances in the subnormal range, where rounding is absolute, and an origin on
# a far plane (t_out = 0).
SLACK = 1.0 + 1e-15
SLACK_ABS = 1e-300


def _plane_offsets(builder, planes, origin):
    """The six bounds (lo x, y, z, hi x, y, z) minus the ray origin's coordinates on
    their axes: the first operation of the slab test, the one rays from one origin
    share."""
    return [builder.fsub(planes[q], origin[q % 3]) for q in range(6)]


def _slab_test(builder, offsets, inv, bound):
    """(entry, entered) per lane: the slab test on float64 vectors (any width),
    ``offsets`` the six bounds less the ray's origin (:func:`_plane_offsets`), ``inv``
    the ray's inverse direction, ``bound`` the farthest entry kept. Every operation is
    the scalar test's (Kay and Kajiya 1986), in its order: t_in = max of the slabs'
    near distances and 0, t_out = min of their far ones, entered when
    ``t_in <= t_out SLACK + SLACK_ABS`` and ``t_in <= bound SLACK + SLACK_ABS``."""
    near, far = [], []
    for a in range(3):
        t0 = builder.fmul(offsets[a], inv[a])
        t1 = builder.fmul(offsets[3 + a], inv[a])
        near.append(_min(builder, t0, t1))
        far.append(_max(builder, t0, t1))
    vector = offsets[0].type
    width = vector.count

    def constant(x):
        return ir.Constant(vector, [x] * width)

    t_in = _max(builder, _max(builder, near[0], near[1]), _max(builder, near[2],
                                                                constant(0.0)))
    t_out = _min(builder, _min(builder, far[0], far[1]), far[2])
    slack = builder.fadd(builder.fmul(t_out, constant(SLACK)), constant(SLACK_ABS))
    # The bound with the same slack, at most the largest float (a missed box's +inf
    # must fail it): hsr.algorithms.bvh.boxes.slack_bound.
    limit = _min(builder, builder.fadd(builder.fmul(bound, constant(SLACK)),
                                       constant(SLACK_ABS)), constant(sys.float_info.max))
    entered = builder.and_(builder.fcmp_ordered("<=", t_in, slack),
                           builder.fcmp_ordered("<=", t_in, limit))
    return builder.select(entered, t_in, constant(float("inf"))), entered


def _keys(builder, entries, lanes):
    """The entries' IEEE bits with the lowest three replaced by the lane (see
    :func:`sort_keys8`): ``<8 x i32>`` keys of float32 entries, ``<8 x i64>`` of float64
    ones."""
    kind = _K8 if entries.type.element == ir.FloatType() else _L8
    return builder.or_(builder.and_(builder.bitcast(entries, kind),
                                    ir.Constant(kind, [~7] * 8)), ir.Constant(kind, lanes))


def _record_pointer(context, builder, array_type, array, record, element):
    """A pointer to wide node ``record`` of a node array (records of
    :data:`NODE_BYTES`, one after another), to ``element``: a shift, where the array's
    row stride would be a multiplication on the walk's chain of dependent reads."""
    ary = context.make_array(array_type)(context, builder, array)
    raw = builder.bitcast(ary.data, ir.IntType(8).as_pointer())
    offset = builder.mul(record, _i64(NODE_BYTES))
    return builder.bitcast(builder.gep(raw, [offset]), element.as_pointer())


def _node_array(array):
    """Whether ``array`` can be read as wide node records: 2-D, C-contiguous, 4-byte
    words (:func:`hsr.algorithms.bvh.layout.node_records` makes them so)."""
    return (isinstance(array, types.Array) and array.ndim == 2 and array.layout == "C"
            and array.dtype in (types.float32, types.int32))


def _box_test8(context, builder, arg_types, args):
    """(key entry, entered) of the float32 slab test of a ray against the eight boxes
    of wide node ``w`` (``args``: box, w, ox, oy, oz, inv_dx, inv_dy, inv_dz, pad,
    bound; see :func:`box_keys8`): the key entry is ``max(t_in - pad, 0)`` (float32),
    +inf where the box is not entered."""
    array, row, ox, oy, oz, ix, iy, iz, pad, bound = args[:10]
    row = context.cast(builder, row, arg_types[1], types.intp)
    base = _record_pointer(context, builder, arg_types[0], array, row, ir.FloatType())

    def lanes(q):
        """Bound q (lo x, y, z, hi x, y, z) of the eight boxes."""
        p = builder.bitcast(builder.gep(base, [_i64(8 * q)]), _F8.as_pointer())
        return builder.load(p, align=4)

    origin = [_splat(builder, x, 8) for x in (ox, oy, oz)]
    inv = [_splat(builder, x, 8) for x in (ix, iy, iz)]
    near, far = [], []
    for a in range(3):
        t0 = builder.fmul(builder.fsub(lanes(a), origin[a]), inv[a])
        t1 = builder.fmul(builder.fsub(lanes(3 + a), origin[a]), inv[a])
        near.append(_min(builder, t0, t1))
        far.append(_max(builder, t0, t1))
    zero = ir.Constant(_F8, [0.0] * 8)
    t_in = _max(builder, _max(builder, near[0], near[1]), _max(builder, near[2], zero))
    t_out = _min(builder, _min(builder, far[0], far[1]), far[2])
    padding = _splat(builder, pad, 8)
    entered = builder.and_(builder.fcmp_ordered("<=", t_in, builder.fadd(t_out, padding)),
                           builder.fcmp_ordered("<=", t_in, _splat(builder, bound, 8)))
    key = _max(builder, builder.fsub(t_in, padding), zero)
    return builder.select(entered, key, ir.Constant(_F8, [float("inf")] * 8)), entered


def _box_test_types(box, scalars):
    """Whether the box tests can take these arguments (a node array, float32 ray)."""
    return _node_array(box) and box.dtype == types.float32 and all(
        s == types.float32 for s in scalars)


@intrinsic
def box_keys8(typingctx, box, w, ox, oy, oz, inv_dx, inv_dy, inv_dz, pad, bound, keys):
    """Where the ray enters each of the eight boxes of wide node ``w`` of ``box`` (the
    float32 records of :func:`hsr.algorithms.bvh.layout.node_records`, a record starting
    with the lanes ``[lo_x * 8, lo_y * 8, lo_z * 8, hi_x * 8, hi_y * 8, hi_z * 8]``),
    written to ``keys`` (int32, 8 contiguous) as the keys of :func:`sort_keys8` (the
    float32 entry's bits, lane in the lowest three; +inf for a box missed or entered
    beyond the bound). Returns the mask of entered boxes, bit k for box k (an int64, 0 ..
    255). The keys are 32-bit, one 256-bit vector, which the closest-hit walk orders
    faster than float64 keys (measurements: docs/history.md, "Ray core").

    The slab test (Kay and Kajiya 1986) in float32, eight lanes in one AVX2 register:
    t_in = max of the slabs' near distances and 0, t_out = min of their far ones. The
    ray comes as :func:`hsr.algorithms.bvh.boxes.box_frame` makes it (origin and inverse
    direction rounded to float32, a ``pad`` that bounds the rounding of every distance,
    Ize 2013), the bound as :func:`hsr.algorithms.bvh.boxes.box_bound` raises it: a box
    is entered when ``t_in <= t_out + pad`` and ``t_in <= bound``, so every box the exact
    ray enters within the bound is, and its key ``max(t_in - pad, 0)`` is at most the
    exact entry (the walk prunes by comparing keys with its bound)."""
    if not (_box_test_types(box, (ox, oy, oz, inv_dx, inv_dy, inv_dz, pad, bound))
            and _key_array(keys, types.int32)):
        return None
    sig = types.int64(box, w, ox, oy, oz, inv_dx, inv_dy, inv_dz, pad, bound, keys)

    def codegen(context, builder, sig, args):
        entry, entered = _box_test8(context, builder, sig.args, args)
        builder.store(_keys(builder, entry, list(range(8))),
                      _keys_pointer(context, builder, sig.args[10], args[10]), align=4)
        return builder.zext(builder.bitcast(entered, ir.IntType(8)), _I64)

    return sig, codegen


@intrinsic
def box_mask8(typingctx, box, w, ox, oy, oz, inv_dx, inv_dy, inv_dz, pad, bound):
    """The mask of :func:`box_keys8` alone, for walks whose bound never shrinks (any
    hit, every hit): the order of the boxes does not matter to them, so their entries
    are not needed."""
    if not _box_test_types(box, (ox, oy, oz, inv_dx, inv_dy, inv_dz, pad, bound)):
        return None
    sig = types.int64(box, w, ox, oy, oz, inv_dx, inv_dy, inv_dz, pad, bound)

    def codegen(context, builder, sig, args):
        _, entered = _box_test8(context, builder, sig.args, args)
        return builder.zext(builder.bitcast(entered, ir.IntType(8)), _I64)

    return sig, codegen


@intrinsic
def record_words(typingctx, link, w, first, second):
    """Words ``first`` and ``second`` of wide node record ``w`` of ``link`` (int32
    records of :func:`hsr.algorithms.bvh.layout.node_records`), as two int64: the
    record found by a shift (:func:`_record_pointer`), the words by constant offsets."""
    if not (_node_array(link) and link.dtype == types.int32):
        return None
    sig = types.UniTuple(types.int64, 2)(link, w, first, second)

    def codegen(context, builder, sig, args):
        array, w_v, a_v, b_v = args
        w_v = context.cast(builder, w_v, sig.args[1], types.intp)
        base = _record_pointer(context, builder, sig.args[0], array, w_v, _I32)
        words = []
        for v, t in ((a_v, sig.args[2]), (b_v, sig.args[3])):
            at = context.cast(builder, v, t, types.intp)
            words.append(builder.sext(builder.load(builder.gep(base, [at])), _I64))
        return context.make_tuple(builder, sig.return_type, words)

    return sig, codegen


def _spread8(builder, bits):
    """Bit k of an 8-bit mask (an i64) moved to bit 4 k (three shift-or-mask steps)."""
    x = bits
    for shift, keep in ((12, 0x000F000F), (6, 0x03030303), (3, 0x11111111)):
        x = builder.and_(builder.or_(x, builder.shl(x, _i64(shift))), _i64(keep))
    return x


def _packet_keys8(shared_origin):
    """The codegen of :func:`packet_keys8` (``shared_origin`` False) and
    :func:`packet_keys8_shared` (True)."""

    def codegen(context, builder, sig, args):
        array, row, rays_v, bound_v, active_v, out_v, keys_v = args
        row = context.cast(builder, row, sig.args[1], types.intp)
        active_v = context.cast(builder, active_v, sig.args[4], types.int64)
        base = _row_pointer(context, builder, sig.args[0], array, row)

        def data(k):
            return context.make_array(sig.args[k])(context, builder, args[k]).data

        ray = data(2)
        limit = data(3)
        entries = builder.bitcast(data(5), _D8.as_pointer())
        planes = []
        for q in range(6):
            p = builder.bitcast(builder.gep(base, [_i64(8 * q)]), _F8.as_pointer())
            planes.append(builder.fpext(builder.load(p, align=4), _D8))
        inf = ir.Constant(_D8, [float("inf")] * 8)
        nearest = inf
        mask = _i64(0)

        def scalar(pointer, at):
            return _splat(builder, builder.load(builder.gep(pointer, [_i64(at)])), 8)

        def offsets(r):
            return _plane_offsets(builder, planes, [scalar(ray, 4 * a + r) for a in range(3)])

        shared = offsets(0) if shared_origin else None
        for r in range(4):
            entry, entered = _slab_test(builder, shared if shared_origin else offsets(r),
                                        [scalar(ray, 4 * (3 + a) + r) for a in range(3)],
                                        scalar(limit, r))
            builder.store(entry, builder.gep(entries, [_i64(r)]), align=8)
            walking = builder.trunc(builder.lshr(active_v, _i64(r)), ir.IntType(1))
            entered = builder.and_(entered, builder.select(
                walking, ir.Constant(ir.VectorType(ir.IntType(1), 8), [1] * 8),
                ir.Constant(ir.VectorType(ir.IntType(1), 8), [0] * 8)))
            nearest = _min(builder, nearest, builder.select(entered, entry, inf))
            bits = builder.zext(builder.bitcast(entered, ir.IntType(8)), _I64)
            mask = builder.or_(mask, builder.shl(_spread8(builder, bits), _i64(r)))
        builder.store(_keys(builder, nearest, list(range(8))),
                      builder.bitcast(data(6), _L8.as_pointer()), align=8)
        return mask

    return codegen


@intrinsic
def packet_keys8(typingctx, box, w, rays, bound, active, out, keys):
    """The slab test of :func:`box_keys8` for a packet of four rays (Wald et al. 2001)
    against the eight boxes of row ``w``, ray by ray, each ray's eight boxes as one
    ``<8 x double>`` vector (the node's bounds are read and widened once for the
    four): ``rays`` (6, 4) float64, the rows origin x, y, z and inverse direction x, y,
    z of the four rays; ``bound`` (4,) each ray's bound; ``active`` the mask of the
    rays walking this node (bit r). Writes ``out[r, k]`` ((4, 8) float64), where ray r
    enters box k (+inf: missed, or entered beyond its bound), and ``keys`` (int64, 8
    contiguous): per box the nearest entry of its active rays as a key of
    :func:`sort_keys8` (+inf when none enters it). Returns the mask of the active rays'
    entries, bit ``4 k + r``. Each ray's arithmetic is the scalar test's, in the same
    order, so its entries are bit for bit those of the one-ray test."""
    if any(a.layout != "C" for a in (rays, bound, out, keys)):
        return None  # read as raw rows: a typing error, not a wrong answer
    sig = types.int64(box, w, rays, bound, active, out, keys)
    return sig, _packet_keys8(False)


@intrinsic
def packet_keys8_shared(typingctx, box, w, rays, bound, active, out, keys):
    """:func:`packet_keys8` for four rays from one origin (a camera's): the bounds less
    the origin are computed once for the four rays (the origin read from ray 0; the
    caller checks that the four are equal). The same arithmetic, so the same entries bit
    for bit, with 6 of the 24 subtractions (measurements: docs/history.md, "Ray core")."""
    if any(a.layout != "C" for a in (rays, bound, out, keys)):
        return None
    sig = types.int64(box, w, rays, bound, active, out, keys)
    return sig, _packet_keys8(True)


def _corners(array):
    """Whether ``array`` can be read as the walks' corners
    (:mod:`hsr.algorithms.bvh.layout`: rows (T, 9) or blocks (Q, 36)): 2-D,
    C-contiguous, float32 or float64."""
    return (isinstance(array, types.Array) and array.ndim == 2 and array.layout == "C"
            and array.dtype in (types.float32, types.float64))


def _leaf_offsets(context, builder, tris_type, array, base_v, lanes_v, axes, origin):
    """The corners of the four slots from ``base`` (rows, or the block that starts
    there: :mod:`hsr.algorithms.bvh.layout`, told apart by the array's width) on the
    permuted axes (``axes`` kx, ky, kz as intp values) less the ray origin's coordinates
    on them (``origin`` okx, oky, okz, scalars): three lists of three ``<4 x double>``
    (corner j's x, y, z; a lane per slot). In blocks each is one vector load, the axis
    an offset into the block; in rows a load and an insert per lane, the lanes not in
    ``lanes`` repeating slot ``base`` (so no row past the leaf is read). The scalar
    test's first step (:func:`hsr.algorithms.bvh.triangle.sheared_corners`), corners
    widened to float64."""
    ary = context.make_array(tris_type)(context, builder, array)
    stride = cgutils.unpack_tuple(builder, ary.strides, 2)[0]
    width = cgutils.unpack_tuple(builder, ary.shape, 2)[1]
    raw = builder.bitcast(ary.data, ir.IntType(8).as_pointer())
    element = context.get_value_type(tris_type.dtype)
    size = context.get_abi_sizeof(element)

    def from_block():
        # (base is a multiple of 4, a block's first slot: layout.leaf_base.)
        block = builder.gep(raw, [builder.mul(builder.ashr(base_v, _i64(2)), stride)])
        vector = ir.VectorType(element, 4)

        def corner(j, axis):
            """Coordinate ``axis`` of corner j of the block's four slots."""
            at = builder.add(builder.mul(axis, _i64(4 * size)), _i64(12 * size * j))
            x = builder.load(builder.bitcast(builder.gep(block, [at]), vector.as_pointer()),
                             align=size)
            return x if element == ir.DoubleType() else builder.fpext(x, _D4)

        return [[corner(j, axes[a]) for j in range(3)] for a in range(3)]

    def from_rows():
        rows = []
        for i in range(4):
            kept = builder.icmp_signed("!=", builder.and_(lanes_v, _i64(1 << i)), _i64(0))
            row = builder.add(base_v, builder.select(kept, _i64(i), _i64(0)))
            rows.append(builder.gep(raw, [builder.mul(row, stride)]))

        def corner(j, axis):
            """Coordinate ``axis`` of corner j of the four slots, a load per lane."""
            v = ir.Constant(_D4, ir.Undefined)
            offset = builder.mul(builder.add(_i64(3 * j), axis), _i64(size))
            for i in range(4):
                p = builder.bitcast(builder.gep(rows[i], [offset]), element.as_pointer())
                x = builder.load(p)
                if element != ir.DoubleType():
                    x = builder.fpext(x, ir.DoubleType())
                v = builder.insert_element(v, x, ir.Constant(_I32, i))
            return v

        return [[corner(j, axes[a]) for j in range(3)] for a in range(3)]

    splat = [_splat(builder, x) for x in origin]
    # The layout by the array's width, layout.BLOCK_VALUES (36) in blocks (one array
    # type for both layouts: the walks compile once).
    blocked = builder.icmp_signed("==", width, _i64(36))
    with builder.if_else(blocked) as (then, otherwise):
        with then:
            in_block = from_block()
            block_end = builder.basic_block
        with otherwise:
            in_rows = from_rows()
            rows_end = builder.basic_block
    values = [[builder.phi(_D4) for j in range(3)] for a in range(3)]
    for a in range(3):
        for j in range(3):
            values[a][j].add_incoming(in_block[a][j], block_end)
            values[a][j].add_incoming(in_rows[a][j], rows_end)
    return [[builder.fsub(values[a][j], splat[a]) for j in range(3)] for a in range(3)]


def _leaf_edges(builder, offsets, sx, sy):
    """The watertight test's 2-D edge values u, v, w and their sum det, four slots'
    ``<4 x double>`` each, for the ray of shear ``sx``, ``sy`` (scalars) and the corners
    less its origin ``offsets`` (:func:`_leaf_offsets`), in the scalar test's operations
    and order (:func:`hsr.algorithms.bvh.triangle.intersect`)."""
    (dx, dy, zs), shear_x, shear_y = offsets, _splat(builder, sx), _splat(builder, sy)
    xs = [builder.fsub(dx[j], builder.fmul(shear_x, zs[j])) for j in range(3)]
    ys = [builder.fsub(dy[j], builder.fmul(shear_y, zs[j])) for j in range(3)]
    (ax, bx, cx), (ay, by, cy) = xs, ys
    u = builder.fsub(builder.fmul(cx, by), builder.fmul(cy, bx))
    v = builder.fsub(builder.fmul(ax, cy), builder.fmul(ay, cx))
    w = builder.fsub(builder.fmul(bx, ay), builder.fmul(by, ax))
    return u, v, w, builder.fadd(builder.fadd(u, v), w)


def _leaf_hits(builder, edges, lanes):
    """Bit i set unless the watertight test rules slot i out (see :func:`leaf_filter4`),
    from its edge values ``edges`` (:func:`_leaf_edges`), of the slots in ``lanes`` (an
    i64 mask); an i64 of four bits."""
    u, v, w, det = edges
    zero = ir.Constant(_D4, [0.0] * 4)

    def any3(op):
        return builder.or_(builder.or_(builder.fcmp_ordered(op, u, zero),
                                       builder.fcmp_ordered(op, v, zero)),
                           builder.fcmp_ordered(op, w, zero))

    miss = builder.or_(builder.and_(any3("<"), any3(">")),
                       builder.fcmp_ordered("==", det, zero))
    bits = builder.zext(builder.bitcast(builder.not_(miss), ir.IntType(4)), _I64)
    return builder.and_(bits, lanes)


def _one_ray_offsets(context, builder, sig, args):
    """:func:`_leaf_offsets` for one ray's leaf test, whose arguments begin ``(tris,
    base, lanes, okx, oky, okz, kx, ky, kz, ...)`` (:func:`leaf_filter4`,
    :func:`leaf_test4`): the offsets, and ``lanes`` as an i64."""
    array, base_v, lanes_v, okx, oky, okz, kx, ky, kz = args[:9]
    base_v = context.cast(builder, base_v, sig.args[1], types.intp)
    lanes_v = context.cast(builder, lanes_v, sig.args[2], types.int64)
    axes = [context.cast(builder, v, t, types.intp) for v, t in zip((kx, ky, kz), sig.args[6:9])]
    return _leaf_offsets(context, builder, sig.args[0], array, base_v, lanes_v, axes,
                         (okx, oky, okz)), lanes_v


@intrinsic
def leaf_filter4(typingctx, tris, base, lanes, okx, oky, okz, kx, ky, kz, sx, sy):
    """Which of the four slots from ``base`` of ``tris`` (the walks' corners, rows or
    blocks, float64 or float32: :mod:`hsr.algorithms.bvh.layout`; in blocks ``base`` a
    multiple of 4, :func:`hsr.algorithms.bvh.layout.leaf_base`) among ``lanes`` (a mask
    of four bits, slot base + i at bit i) the ray can hit: bit i set unless the
    watertight test (:func:`hsr.algorithms.bvh.triangle.intersect`, Woop, Benthin & Wald
    2013) finds the edge values of slot base + i of mixed signs or their sum zero, its
    misses before any culling. The four slots are the lanes of ``<4 x double>`` vectors,
    each lane computed with the scalar test's operations in its order (corners widened
    to float64, no fused multiply-adds), so a lane is cleared exactly when the scalar
    test returns its miss there; the caller runs the scalar test on the lanes left (a
    hit or a culled face; most triangles a ray tests it misses)."""
    if not _corners(tris):
        return None
    sig = types.int64(tris, base, lanes, okx, oky, okz, kx, ky, kz, sx, sy)

    def codegen(context, builder, sig, args):
        offsets, lanes_v = _one_ray_offsets(context, builder, sig, args)
        return _leaf_hits(builder, _leaf_edges(builder, offsets, args[9], args[10]), lanes_v)

    return sig, codegen


@intrinsic
def leaf_test4(typingctx, tris, base, lanes, okx, oky, okz, kx, ky, kz, sx, sy, sz, out):
    """:func:`leaf_filter4`'s bits, and the rest of the watertight test
    (:func:`hsr.algorithms.bvh.triangle.intersect` without culling) in the same four
    lanes, so that the slots left need no scalar test: ``out`` ((5, 4) float64,
    C-contiguous) gets, lane i for slot base + i, the numerator of the hit's distance
    (row 0), the edge values u, v, w (rows 1 .. 3) and their sum det (row 4), each with
    the scalar test's operations in its order: row / det is then bit for bit the scalar
    test's t, u, v, w (for the lanes whose bit is set; the others hold whatever they
    compute to). The divisions are the caller's, for the few lanes left: dividing all
    four lanes in the vector made the walk slower (measurements: docs/history.md, "Ray
    core")."""
    if not _corners(tris) or not (isinstance(out, types.Array) and out.ndim == 2
                                  and out.layout == "C" and out.dtype == types.float64):
        return None
    sig = types.int64(tris, base, lanes, okx, oky, okz, kx, ky, kz, sx, sy, sz, out)

    def codegen(context, builder, sig, args):
        offsets, lanes_v = _one_ray_offsets(context, builder, sig, args)
        sx, sy, sz, out_v = args[9:13]
        u, v, w, det = edges = _leaf_edges(builder, offsets, sx, sy)
        # t = (u (sz az) + v (sz bz) + w (sz cz)) / det, as the scalar test sums it.
        shear_z = _splat(builder, sz)
        zs = offsets[2]
        t = builder.fadd(builder.fadd(
            builder.fmul(u, builder.fmul(shear_z, zs[0])),
            builder.fmul(v, builder.fmul(shear_z, zs[1]))),
            builder.fmul(w, builder.fmul(shear_z, zs[2])))
        rows = builder.bitcast(context.make_array(sig.args[12])(context, builder, out_v).data,
                               _D4.as_pointer())
        for r, value in enumerate((t, u, v, w, det)):
            builder.store(value, builder.gep(rows, [_i64(r)]), align=8)
        return _leaf_hits(builder, edges, lanes_v)

    return sig, codegen


@intrinsic
def leaf_filter4_rays(typingctx, tris, base, lanes, frame, axes):
    """:func:`leaf_filter4` for the four rays of a packet that share their origin and
    their permuted axes (a camera's rays mostly do), so that what their tests share, the
    corners read on those axes less the origin, is done once: ``frame`` (11, 4) float64
    as :func:`hsr.algorithms.bvh.packets.trace_packets` keeps it (rows sx, sy, then okx, oky,
    okz; a column per ray, the origin read from ray 0's), ``axes`` (3, 4) int64 (kx,
    ky, kz of ray 0). Returns the four rays' bits of :func:`leaf_filter4`, ray r's at
    bits 4 r .. 4 r + 3; each the same bits, as the same arithmetic."""
    if not _corners(tris) or frame.layout != "C" or axes.layout != "C":
        return None  # read as raw rows: a typing error, not a wrong answer
    sig = types.int64(tris, base, lanes, frame, axes)

    def codegen(context, builder, sig, args):
        array, base_v, lanes_v, frame_v, axes_v = args
        base_v = context.cast(builder, base_v, sig.args[1], types.intp)
        lanes_v = context.cast(builder, lanes_v, sig.args[2], types.int64)
        values = context.make_array(sig.args[3])(context, builder, frame_v).data
        ints = context.make_array(sig.args[4])(context, builder, axes_v).data

        def load(pointer, at):
            return builder.load(builder.gep(pointer, [_i64(at)]))

        axes = [load(ints, 4 * a) for a in range(3)]
        offsets = _leaf_offsets(context, builder, sig.args[0], array, base_v, lanes_v, axes,
                                [load(values, 4 * (3 + a)) for a in range(3)])
        bits = _i64(0)
        for r in range(4):
            hits = _leaf_hits(builder, _leaf_edges(builder, offsets, load(values, r),
                                                   load(values, 4 + r)), lanes_v)
            bits = builder.or_(bits, builder.shl(hits, _i64(4 * r)))
        return bits

    return sig, codegen


# Batcher's odd-even merge sort for eight keys: 19 comparators in six rounds.
_ROUNDS8 = ([(0, 1), (2, 3), (4, 5), (6, 7)], [(0, 2), (1, 3), (4, 6), (5, 7)],
            [(1, 2), (5, 6)], [(0, 4), (1, 5), (2, 6), (3, 7)], [(2, 4), (3, 5)],
            [(1, 2), (3, 4), (5, 6)])


def _key_array(array, dtype=None):
    """Whether ``array`` can hold eight keys of :func:`sort_keys8`: 1-D, C-contiguous,
    int32 or int64 (``dtype`` alone, if given)."""
    return (isinstance(array, types.Array) and array.ndim == 1 and array.layout == "C"
            and array.dtype in ((dtype,) if dtype else (types.int32, types.int64)))


def _keys_pointer(context, builder, array_type, array):
    """The eight keys of ``array`` (contiguous, int32 or int64) as one ``<8 x i32>`` or
    ``<8 x i64>`` pointer."""
    kind = _K8 if array_type.dtype == types.int32 else _L8
    return builder.bitcast(context.make_array(array_type)(context, builder, array).data,
                           kind.as_pointer())


def _permuted(builder, v, lanes):
    """``v`` (eight lanes) with its lanes in the order ``lanes``."""
    return builder.shuffle_vector(v, ir.Constant(v.type, ir.Undefined),
                                  ir.Constant(ir.VectorType(_I32, 8), lanes))


@intrinsic
def min_key8(typingctx, keys):
    """The least of the eight ``keys`` (int32 or int64, 8 contiguous; :func:`sort_keys8`'s
    keys), as an int64: the nearest entered lane's, in three rounds of vector min with
    shuffles. The ordered walk takes its next box from it while the sorting network
    orders the rest for the stack: six rounds fewer between a node's box test and the
    next node's read (measurements: docs/history.md, "Ray core")."""
    if not _key_array(keys):
        return None
    sig = types.int64(keys)

    def codegen(context, builder, sig, args):
        v = builder.load(_keys_pointer(context, builder, sig.args[0], args[0]), align=4)
        for partner in ([4, 5, 6, 7, 0, 1, 2, 3], [2, 3, 0, 1, 6, 7, 4, 5],
                        [1, 0, 3, 2, 5, 4, 7, 6]):
            other = _permuted(builder, v, partner)
            v = builder.select(builder.icmp_signed("<", v, other), v, other)
        least = builder.extract_element(v, ir.Constant(_I32, 0))
        return builder.sext(least, _I64) if v.type == _K8 else least

    return sig, codegen


@intrinsic
def sort_keys8(typingctx, keys):
    """Sort the eight ``keys`` (int32 or int64, 8 contiguous) in place, least first: the
    lanes of a wide node nearest first, when each key is the lane's entry distance (>= 0,
    or +inf for a missed lane) read as its IEEE bits (float32's in int32 keys, as
    :func:`box_keys8` writes them; float64's in int64, the packets'), whose integer order
    is the order of the values, with the three lowest bits replaced by the lane (``key &
    7``). So keys are distinct, entries within eight units in the last place of each
    other go in lane order (the walk's order only sets how soon a hit prunes, never the
    answer), and ``key & ~7`` read back is the entry rounded down by at most seven units
    in the last place, never past the true entry; the pruning compares keys with a
    bound's key whose low bits are all set, so it keeps every box the true entry would
    keep (see :func:`hsr.algorithms.bvh.stack.next_box`).

    Batcher's odd-even merge network as six rounds of vector min and max with
    shuffles: no branch. Scalar selects written in Numba were turned into branches by
    the compiler (seen with ``inspect_asm``), and which lanes are nearest is what a
    random ray makes unpredictable."""
    if not _key_array(keys):
        return None
    sig = types.void(keys)

    def codegen(context, builder, sig, args):
        pointer = _keys_pointer(context, builder, sig.args[0], args[0])
        v = builder.load(pointer, align=4)
        for pairs in _ROUNDS8:
            partner, take = list(range(8)), list(range(8))
            for i, j in pairs:
                partner[i], partner[j] = j, i
                take[j] = 8 + j  # the higher of the pair; i keeps the lower
            other = _permuted(builder, v, partner)
            below = builder.icmp_signed("<", v, other)
            low = builder.select(below, v, other)
            high = builder.select(below, other, v)
            v = builder.shuffle_vector(low, high, ir.Constant(ir.VectorType(_I32, 8), take))
        builder.store(v, pointer, align=4)
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def lowest_bit(typingctx, x):
    """The index of the lowest set bit of an int64 that is not 0 (LLVM's ``cttz``: one
    instruction, where a loop over the bits branches once a bit)."""
    sig = types.int64(types.int64)

    def codegen(context, builder, sig, args):
        fn = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(_I64, [_I64, ir.IntType(1)]), "llvm.cttz.i64")
        return builder.call(fn, [args[0], ir.Constant(ir.IntType(1), 1)])

    return sig, codegen


@intrinsic
def bit_count(typingctx, x):
    """The set bits of an int64 (LLVM's ``ctpop``)."""
    sig = types.int64(types.int64)

    def codegen(context, builder, sig, args):
        fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(_I64, [_I64]),
                                            "llvm.ctpop.i64")
        return builder.call(fn, [args[0]])

    return sig, codegen


@intrinsic
def float_bits(typingctx, x):
    """The IEEE bits of a float64, or of a float32 (its 32 bits, sign-extended), as an
    int64: for a value >= 0 their integer order is the values' order (the keys of
    :func:`sort_keys8`, float64's in the packets, float32's in :func:`box_keys8`)."""
    if x not in (types.float32, types.float64):
        return None
    sig = types.int64(x)

    def codegen(context, builder, sig, args):
        if sig.args[0] == types.float32:
            return builder.sext(builder.bitcast(args[0], _I32), _I64)
        return builder.bitcast(args[0], _I64)

    return sig, codegen


@intrinsic
def grow_box(typingctx, bins, i, prim, k):
    """Grow the box at ``bins[i:i + 8]`` (float64, 1-D: lo x, y, z, a spare word, hi x,
    y, z, a spare word) by the box of row ``k`` of ``prim`` (float64, 2-D, rows of at
    least 7 words starting lo x, y, z, hi x, y, z): two ``<4 x double>`` min / max
    where the scalar code made six, each a load and a store of the bin (the BVH build's
    binning in :mod:`hsr.algorithms.bvh.sah`; measurements: docs/history.md, "Ray
    core"). The spare words take the row's words 3 and 6, and are never read."""
    sig = types.void(bins, i, prim, k)

    def codegen(context, builder, sig, args):
        bins_v, i_v, prim_v, k_v = args
        i_v = context.cast(builder, i_v, sig.args[1], types.intp)
        k_v = context.cast(builder, k_v, sig.args[3], types.intp)
        row = _row_pointer(context, builder, sig.args[2], prim_v, k_v, ir.DoubleType())
        bin_at = builder.gep(context.make_array(sig.args[0])(context, builder, bins_v).data,
                             [i_v])
        pointers = [builder.bitcast(row, _D4.as_pointer()),
                    builder.bitcast(builder.gep(row, [_i64(3)]), _D4.as_pointer()),
                    builder.bitcast(bin_at, _D4.as_pointer()),
                    builder.bitcast(builder.gep(bin_at, [_i64(4)]), _D4.as_pointer())]
        lo, hi, bin_lo, bin_hi = (builder.load(q, align=8) for q in pointers)
        builder.store(_min(builder, lo, bin_lo), pointers[2], align=8)
        builder.store(_max(builder, hi, bin_hi), pointers[3], align=8)
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def next_float32(typingctx, x, up):
    """The float32 next to ``x`` (not NaN) towards +inf when ``up``, else towards -inf:
    ``np.nextafter`` by the bits, as the IEEE layout orders them (a step of one in the
    magnitude's bits; from zero, the smallest subnormal of the step's sign). Numba's
    ``np.nextafter`` calls libm, slow for the wide tree's millions of outward roundings
    (measurements: docs/history.md, "Ray core")."""
    sig = types.float32(types.float32, types.boolean)

    def codegen(context, builder, sig, args):
        value, towards_up = args
        i32 = ir.IntType(32)
        up = builder.trunc(towards_up, ir.IntType(1))
        bits = builder.bitcast(value, i32)
        # Away from zero when the step goes the way of the sign, else towards it.
        away = builder.xor(builder.icmp_signed("<", bits, ir.Constant(i32, 0)), up)
        stepped = builder.select(away, builder.add(bits, ir.Constant(i32, 1)),
                                 builder.sub(bits, ir.Constant(i32, 1)))
        is_zero = builder.fcmp_ordered("==", value, ir.Constant(ir.FloatType(), 0.0))
        tiny = builder.select(up, ir.Constant(i32, 1), ir.Constant(i32, -2**31 + 1))
        out = builder.bitcast(builder.select(is_zero, tiny, stepped), ir.FloatType())
        # An infinity stepped outwards stays where it is.
        end = builder.select(up, ir.Constant(ir.FloatType(), float("inf")),
                             ir.Constant(ir.FloatType(), float("-inf")))
        return builder.select(builder.fcmp_ordered("==", value, end), value, out)

    return sig, codegen


@intrinsic
def prefetch(typingctx, array, row, offset):
    """A hint to bring the cache line at byte ``offset`` of row ``row`` of ``array``
    (rows as its first stride spaces them) towards the core (LLVM's ``llvm.prefetch``:
    read, keep in all cache levels). It reads nothing into the program and cannot fault,
    so results never depend on it; :func:`hsr.algorithms.bvh.walk.trace_range` issues it for
    the node a ray walks next and then turns to another ray while the line comes."""
    sig = types.void(array, row, offset)

    def codegen(context, builder, sig, args):
        data, row_v, offset_v = args
        row_v = context.cast(builder, row_v, sig.args[1], types.intp)
        offset_v = context.cast(builder, offset_v, sig.args[2], types.intp)
        ary = context.make_array(sig.args[0])(context, builder, data)
        stride = cgutils.unpack_tuple(builder, ary.strides, sig.args[0].ndim)[0]
        raw = builder.bitcast(ary.data, ir.IntType(8).as_pointer())
        at = builder.gep(raw, [builder.add(builder.mul(row_v, stride), offset_v)])
        fnty = ir.FunctionType(ir.VoidType(), [ir.IntType(8).as_pointer(), _I32, _I32, _I32])
        fn = cgutils.get_or_insert_function(builder.module, fnty, "llvm.prefetch.p0")
        # rw 0 (read), locality 3 (keep in every level), cache type 1 (data).
        builder.call(fn, [at, ir.Constant(_I32, 0), ir.Constant(_I32, 3), ir.Constant(_I32, 1)])
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def borrowed(typingctx, array):
    """``array`` as a view that holds no reference: the same data, shape and strides
    with a null memory record, as :func:`numba.carray` makes (Numba's reference counts
    skip a null record). For the walks' loops, over arrays their caller keeps alive:
    Numba counts a reference each time an array is handed to an inlined helper (the
    triangle test takes the corners), and where the helper's branches keep the count
    from being pruned that is two atomic instructions in the loop, each waiting for the
    memory reads in flight."""
    if not isinstance(array, types.Array):
        return None

    def codegen(context, builder, signature, args):
        view = context.make_array(signature.args[0])(context, builder, args[0])
        view.meminfo = cgutils.get_null_value(view.meminfo.type)
        view.parent = cgutils.get_null_value(view.parent.type)
        return view._getvalue()
    return array(array), codegen
