"""LLVM wide-integer intrinsics: the exact arithmetic under every predicate.

numba has no integer type wider than 64 bits, but LLVM has ``i128``, ``i192``,
``i256`` and ``i512``, and lowers their ``add``/``mul``/``shl`` to chains of
``adc``/``mulx`` on x86-64 -- the same instruction sequences the paper's C++
builds by hand. Each intrinsic here reads whole wide elements straight from a
C-contiguous wide array (see :mod:`csgnb.exact.wide`), computes in LLVM's native
wide integers and returns a small result (a sign, a bool, a double) or stores
wide values into an output array. The code generation lives in
:mod:`csgnb.exact.lowering`.

The width is read from the array's record dtype at typing time, so one jitted
kernel compiles to a 128-, 192- and 256-bit version on demand, each cached. Plane
operands may be full ``(n, 4)`` rows or narrow plane records
(:mod:`csgnb.exact.planes`); the layout is read from the dtype too, and narrow
planes are computed with narrow products (a product of two int32 normals is one
64-bit ``imul``).

Why wrap-around is harmless: two's-complement ``add``/``sub``/``mul`` are exact
modulo ``2**b``. A polynomial whose *final* value lies in ``[-2**(b-1), 2**(b-1))``
is therefore computed exactly even when partial sums wrap. The bit budgets in
:mod:`csgnb.exact.budgets` bound exactly these final values, and are enforced
where data enters; nothing in here checks for overflow.

All intrinsics take ``(array, row, column)`` style operands: rows are the
leading index, columns the second index of 2-D arrays (planes and homogeneous
points are ``(n, 4)``, integer points ``(n, 3) int64``).
"""

from __future__ import annotations

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.errors import TypingError
from numba.extending import intrinsic

from csgnb.exact import lowering as lw
from csgnb.exact.lowering import F64, I8, I64

__all__ = [
    "classify_at",
    "classify_wall_at",
    "intersect_into",
    "plane_from_points_into",
    "plane_from_normal_into",
    "signed_distance_into",
    "planes_parallel_at",
    "points_equal_at",
    "compare_plane_values_at",
    "translate_point_into",
    "box_plane_sides",
    "compare_cached_values_at",
    "compare_filtered_values_at",
    "plane_value_filtered_into",
    "wide_sign_at",
    "wide_to_float_at",
    "wide_filter_double_at",
    "wide_to_int64_at",
    "wide_split_double_at",
    "wide_abs_greater_at",
    "wide_divexact_at",
    "compare_ratio_dyadic_at",
    "scan_rows",
    "positions_into",
    "trailing_zeros",
    "fma",
    "half_ulp",
    "cross_sign",
    "plane_side_sign",
]


# The names other packages' intrinsics import (csgnb.mesh.volume, csgnb.exact.wide_store): the
# code generation moved to csgnb.exact.lowering.
_wide_width = lw.wide_width
_row_pointer = lw.row_pointer
_element_pointer = lw.element_pointer
_load = lw.load
_load_row = lw.load_row
_store_row = lw.store_row
_sign = lw.sign
_abs = lw.absolute


def _T(bits: int) -> ir.IntType:
    return ir.IntType(bits)


# ---------------------------------------------------------------------------
# predicates


@intrinsic
def classify_at(typingctx, points, i, planes, j):
    """Sign of point ``points[i]`` against plane ``planes[j]``: sign(x·s)·sign(x4) (eq. 6).

    ``points`` is an ``(n, 4)`` wide array, ``planes`` ``(m, 4)`` wide rows or narrow planes, of
    one width. Returns int8: +1 on the positive side, -1 on the negative side, 0 on the plane.
    """
    T = _T(lw.same_width("classify_at", points, planes))

    def codegen(context, builder, sig, args):
        x = lw.load_row(context, builder, sig.args[0], args[0], args[1], sig.args[1], T, 4)
        s = lw.load_plane(context, builder, sig.args[2], args[2], args[3], sig.args[3])
        return lw.sign_times_sign(builder, lw.plane_dot(builder, x, s, T), x[3])

    return types.int8(points, i, planes, j), codegen


@intrinsic
def classify_wall_at(typingctx, points, i, planes, j, axis):
    """:func:`classify_at` for a plane ``planes[j]`` expected on a coordinate axis (a cell box's wall): when its
    other two normal coefficients are zero and its ``axis`` coefficient and offset fit in 64 bits, x·s is
    ``x[axis]·a + x4·d``, two wide-by-word products instead of three and a wide-by-wide one; any other row takes
    :func:`classify_at`'s path (checked at run time: the same sign either way).
    """
    T = _T(lw.same_width("classify_wall_at", points, planes))

    def codegen(context, builder, sig, args):
        x = lw.load_row(context, builder, sig.args[0], args[0], args[1], sig.args[1], T, 4)
        s = lw.load_plane(context, builder, sig.args[2], args[2], args[3], sig.args[3])
        k = context.cast(builder, args[4], sig.args[4], types.int64)
        at = [builder.icmp_signed("==", k, ir.Constant(I64, c)) for c in range(3)]
        xa = builder.select(at[0], x[0], builder.select(at[1], x[1], x[2]))
        na = builder.select(at[0], s[0], builder.select(at[1], s[1], s[2]))
        wide = [v for v in (na, s[3]) if v.type.width > 64]  # narrow plane fields are words already
        wall = lw.fits_in_word(builder, wide) if wide else ir.Constant(ir.IntType(1), 1)
        for c in range(3):  # the other two coefficients are zero
            zero = builder.icmp_signed("==", s[c], ir.Constant(s[c].type, 0))
            wall = builder.and_(wall, builder.or_(at[c], zero))
        value = lw.branch_values(
            builder, wall,
            lambda: [builder.add(lw.mul_exact(builder, xa, lw.resize(builder, na, I64), T),
                                 lw.mul_exact(builder, x[3], lw.resize(builder, s[3], I64), T))],
            lambda: [lw.plane_dot(builder, x, s, T)])[0]
        return lw.sign_times_sign(builder, value, x[3])

    return types.int8(points, i, planes, j, axis), codegen


def _intersect_full(builder, p, q, r):
    """Eq. 5 for planes loaded at the full width: 2x2 minors of q, r shared by four 3x3 cofactors."""
    a_p, b_p, c_p, d_p = p
    a_q, b_q, c_q, d_q = q
    a_r, b_r, c_r, d_r = r
    m_ab = lw.det2(builder, a_q, b_q, a_r, b_r)
    m_ac = lw.det2(builder, a_q, c_q, a_r, c_r)
    m_ad = lw.det2(builder, a_q, d_q, a_r, d_r)
    m_bc = lw.det2(builder, b_q, c_q, b_r, c_r)
    m_bd = lw.det2(builder, b_q, d_q, b_r, d_r)
    m_cd = lw.det2(builder, c_q, d_q, c_r, d_r)
    det_bcd = lw.dot(builder, [b_p, c_p, d_p], [m_cd, builder.neg(m_bd), m_bc])
    det_acd = lw.dot(builder, [a_p, c_p, d_p], [m_cd, builder.neg(m_ad), m_ac])
    det_abd = lw.dot(builder, [a_p, b_p, d_p], [m_bd, builder.neg(m_ad), m_ab])
    det_abc = lw.dot(builder, [a_p, b_p, c_p], [m_bc, builder.neg(m_ac), m_ab])
    return [det_bcd, builder.neg(det_acd), det_abd, builder.neg(det_abc)]


def _intersect_narrow(builder, p, q, r, T, M):
    """Eq. 5 for narrow planes, expanded along the offset column.

    Every cofactor is Σ ±(offset or normal) x (a 2x2 minor of normals); the nine minors are
    exact at ``M`` (twice the normal field: |a| < 2**(k-1) gives |minor| < 2**(2k-1)), so
    they cost one narrow ``imul`` per product, and only the nine offset products and three
    normal products that follow are wide.
    """
    rows = (p, q, r)
    pairs = ((1, 2), (0, 2), (0, 1))  # row pairs (q, r), (p, r), (p, q): the minors for rows p, q, r

    def minors(u, v):
        return [lw.det2(builder, rows[s][u], rows[s][v], rows[t][u], rows[t][v], M) for s, t in pairs]

    def expand(column, ms):
        terms = [lw.mul_exact(builder, rows[k][column], ms[k], T) for k in range(3)]
        return builder.add(builder.sub(terms[0], terms[1]), terms[2])

    m_bc, m_ac, m_ab = minors(1, 2), minors(0, 2), minors(0, 1)
    det_bcd, det_acd, det_abd = expand(3, m_bc), expand(3, m_ac), expand(3, m_ab)
    det_abc = expand(0, m_bc)
    return [det_bcd, builder.neg(det_acd), det_abd, builder.neg(det_abc)]


def _intersect_full_or_word(builder, planes, T):
    """Eq. 5 for full-width rows, decided at run time: when the nine normal coefficients fit in 64 bits (the
    common case: on the 256-bit dome grid the normals reach 2^46, the offsets 2^72), as :func:`_intersect_narrow`
    with 64-bit normal fields (minors one ``imul`` each, the offset products wide times a word); otherwise as
    :func:`_intersect_full`. Both give the same cofactors modulo 2**T.width: the same exact point."""
    def word():
        return [[builder.trunc(v, I64) for v in plane[:3]] + [plane[3]] for plane in planes]

    return lw.branch_values(builder, lw.fits_in_word(builder, [v for plane in planes for v in plane[:3]]),
                            lambda: _intersect_narrow(builder, *word(), T, _T(128)),
                            lambda: _intersect_full(builder, *planes))


@intrinsic
def intersect_into(typingctx, P, ip, Q, iq, R, ir_, out, io):
    """Store intersect(p, q, r) (eq. 5) of planes ``P[ip], Q[iq], R[ir_]`` into ``out[io]``.

    The homogeneous point is the vector of cofactors of the first row of
    ``det[e1 e2 e3 e4; p; q; r]``, so that ``x·s = det[s; p; q; r]`` for any plane
    ``s`` and ``x·p = x·q = x·r = 0``. ``x4 = -det(n_p, n_q, n_r)`` is zero when the
    normals are linearly dependent (no unique intersection). Planes in either layout;
    ``out`` an ``(n, 4)`` wide array of their width.
    """
    bits = lw.same_width("intersect_into", P, Q, R, out)
    lw.wide_width(out, "intersect_into")
    T = _T(bits)
    layouts = [lw.plane_layout(a, "intersect_into") for a in (P, Q, R)]
    narrow = all(layout.narrow for layout in layouts)
    M = _T(2 * layouts[0].normal_bits)

    def values(context, builder, sig, args):
        planes = [lw.load_plane(context, builder, sig.args[2 * k], args[2 * k], args[2 * k + 1], sig.args[2 * k + 1],
                                None if narrow else T) for k in range(3)]
        if narrow:
            return _intersect_narrow(builder, *planes, T, M)
        if T.width <= 128:  # (see lowering.plane_dot: the branch slows the 128-bit bulk loops)
            return _intersect_full(builder, *planes)
        return _intersect_full_or_word(builder, planes, T)

    def codegen(context, builder, sig, args):
        x = values(context, builder, sig, args)
        lw.store_row(context, builder, sig.args[6], args[6], args[7], sig.args[7], T, x)
        return context.get_dummy_value()

    codegen.values = values  # the point without the store, for csgnb.exact.blocks
    return types.none(P, ip, Q, iq, R, ir_, out, io), codegen


@intrinsic
def plane_from_points_into(typingctx, Pt, ip, Qt, iq, Rt, ir_, out, io):
    """Store the plane through integer points ``Pt[ip], Qt[iq], Rt[ir_]`` into ``out[io]``.

    ``n = (q - p) x (r - p)``, ``d = -n·p``; the points are ``(n, 3) int64`` rows and
    all arithmetic is done at the width of ``out`` (wide rows or narrow planes; narrow
    fields take the low bits, which callers keep within the mesh budget). The normal is
    zero for collinear points.
    """
    for a in (Pt, Qt, Rt):
        lw.int_array(a, "plane_from_points_into")
    T = _T(lw.plane_layout(out, "plane_from_points_into").bits)

    def codegen(context, builder, sig, args):
        p = lw.load_row(context, builder, sig.args[0], args[0], args[1], sig.args[1], T, 3)
        q = lw.load_row(context, builder, sig.args[2], args[2], args[3], sig.args[3], T, 3)
        r = lw.load_row(context, builder, sig.args[4], args[4], args[5], sig.args[5], T, 3)
        e1 = [builder.sub(qi, pi) for qi, pi in zip(q, p, strict=True)]
        e2 = [builder.sub(ri, pi) for ri, pi in zip(r, p, strict=True)]
        n = [
            lw.det2(builder, e1[1], e1[2], e2[1], e2[2]),
            lw.det2(builder, e1[2], e1[0], e2[2], e2[0]),
            lw.det2(builder, e1[0], e1[1], e2[0], e2[1]),
        ]
        d = builder.neg(lw.dot(builder, n, p))
        lw.store_plane(context, builder, sig.args[6], args[6], args[7], sig.args[7], n + [d])
        return context.get_dummy_value()

    return types.none(Pt, ip, Qt, iq, Rt, ir_, out, io), codegen


@intrinsic
def plane_from_normal_into(typingctx, a, b, c, Pt, ip, out, io):
    """Store the plane with int64 normal (a, b, c) through the integer point ``Pt[ip]`` into ``out[io]``.

    ``d = -(a, b, c)·p`` is formed from 64 x 64-bit products at the width of ``out`` (either
    layout), so a kernel that computed and reduced the normal in int64 (planes through mesh
    vertices: |n| <= 8 V^2 < 2**57) finishes the plane with three ``imul``.
    """
    lw.int_array(Pt, "plane_from_normal_into")
    T = _T(lw.plane_layout(out, "plane_from_normal_into").bits)

    def codegen(context, builder, sig, args):
        n = [context.cast(builder, v, ty, types.int64) for v, ty in zip(args[:3], sig.args[:3], strict=True)]
        p = lw.load_row(context, builder, sig.args[3], args[3], args[4], sig.args[4], I64, 3)
        d = builder.neg(lw.dot(builder, n, p, T))
        lw.store_plane(context, builder, sig.args[5], args[5], args[6], sig.args[6], n + [d])
        return context.get_dummy_value()

    return types.none(a, b, c, Pt, ip, out, io), codegen


@intrinsic
def signed_distance_into(typingctx, pts, i, planes, j, out, io):
    """Store ``n·v + d`` of integer point ``pts[i]`` ((n, 3) int64) and plane ``planes[j]`` into ``out[io]``.

    The value is the signed distance scaled by |n| (exact, no division). ``planes`` in either
    layout; ``out`` a 1-D wide array of their width.
    """
    lw.int_array(pts, "signed_distance_into")
    T = _T(lw.same_width("signed_distance_into", planes, out))

    def codegen(context, builder, sig, args):
        v = lw.load_row(context, builder, sig.args[0], args[0], args[1], sig.args[1], I64, 3)
        s = lw.load_plane(context, builder, sig.args[2], args[2], args[3], sig.args[3])
        value = builder.add(lw.dot(builder, v, s[:3], T), lw.resize(builder, s[3], T))
        lw.store_row(context, builder, sig.args[4], args[4], args[5], sig.args[5], T, [value])
        return context.get_dummy_value()

    return types.none(pts, i, planes, j, out, io), codegen


@intrinsic
def translate_point_into(typingctx, X, i, shift, j, out, io):
    """Store the homogeneous point ``X[i]`` moved by the integer vector ``shift[j]`` ((n, 3) int64) into ``out[io]``:
    ``(x + t·x4, x4)``, each coordinate a wide-times-word product and a sum (``X`` and ``out`` wide, one width).

    This is exactly the point the moved planes ``(n, d - n·t)`` meet in (eq. 5 of the moved planes gives it bit for
    bit: the plane map ``(n, d) -> (n, d - n·t)`` has determinant 1), so a translated tool's vertices need no new
    intersections. The caller keeps the moved point within the width (the moved planes' budget does)."""
    lw.int_array(shift, "translate_point_into")
    T = _T(lw.same_width("translate_point_into", X, out))

    def codegen(context, builder, sig, args):
        x = lw.load_row(context, builder, sig.args[0], args[0], args[1], sig.args[1], T, 4)
        t = lw.load_row(context, builder, sig.args[2], args[2], args[3], sig.args[3], I64, 3)
        moved = [builder.add(x[c], lw.mul_exact(builder, x[3], t[c], T)) for c in range(3)] + [x[3]]
        lw.store_row(context, builder, sig.args[4], args[4], args[5], sig.args[5], T, moved)
        return context.get_dummy_value()

    return types.none(X, i, shift, j, out, io), codegen


@intrinsic
def box_plane_sides(typingctx, pts, i, size, planes, j):
    """Which sides of plane ``planes[j]`` the corners of the cube ``pts[i] + [0, size]^3`` reach (``pts`` (n, 3) int64).

    Returns int8 ``1`` (a corner strictly negative) ``| 2`` (a corner strictly positive). The linear function
    n·v + d takes its extremes over the box at corners: at ``lo`` plus ``size`` times the negative (positive) normal
    components, so ``min = n·lo + d + size·Σ min(n_k, 0)``, ``max = n·lo + d + size·Σ max(n_k, 0)``: five products
    instead of the 24 of eight :func:`signed_distance_into` calls. Exact whenever those are: both values are corner
    distances, and the arithmetic modulo ``2**width`` gives any value that fits exactly, whatever the partial sums.
    """
    lw.int_array(pts, "box_plane_sides")
    T = _T(lw.same_width("box_plane_sides", planes))

    def codegen(context, builder, sig, args):
        lo = lw.load_row(context, builder, sig.args[0], args[0], args[1], sig.args[1], I64, 3)
        w = context.cast(builder, args[2], sig.args[2], types.int64)
        s = lw.load_plane(context, builder, sig.args[3], args[3], args[4], sig.args[4])
        base = builder.add(lw.dot(builder, lo, s[:3], T), lw.resize(builder, s[3], T))
        zero = ir.Constant(T, 0)
        low, high = zero, zero
        for n in s[:3]:
            n = lw.resize(builder, n, T)
            negative = builder.icmp_signed("<", n, zero)
            low = builder.add(low, builder.select(negative, n, zero))
            high = builder.add(high, builder.select(negative, zero, n))
        vmin = builder.add(base, lw.mul_exact(builder, w, low, T))
        vmax = builder.add(base, lw.mul_exact(builder, w, high, T))
        neg = builder.zext(builder.icmp_signed("<", vmin, zero), I8)
        pos = builder.zext(builder.icmp_signed(">", vmax, zero), I8)
        return builder.or_(neg, builder.shl(pos, ir.Constant(I8, 1)))

    return types.int8(pts, i, size, planes, j), codegen


@intrinsic
def planes_parallel_at(typingctx, P, i, Q, j):
    """Whether the normals of ``P[i]`` and ``Q[j]`` are parallel: n_p x n_q = 0 (eq. 1).

    The cross product is tested for zero modulo ``2**M``, which is exact as long as its
    components stay below ``2**(M-1)``: narrow normals (|a| < 2**31 or 2**63) use twice the
    normal field; full rows use what the budget allows -- every plane within the budget of
    its width has ``27 N^6 < 2**(2b-2)``, i.e. ``2 N^2 < 2**127`` at 192 bits and ``< 2**170``
    at 256, so products are formed at 128 and 192 bits instead of 192 and 256.
    """
    lp, lq = lw.plane_layout(P, "planes_parallel_at"), lw.plane_layout(Q, "planes_parallel_at")
    bits = lw.same_width("planes_parallel_at", P, Q)
    if lp.narrow and lq.narrow:
        M = _T(2 * lp.normal_bits)
    else:
        M = _T({128: 128, 192: 128, 256: 192}[bits])

    def codegen(context, builder, sig, args):
        a1, b1, c1, _ = lw.load_plane(context, builder, sig.args[0], args[0], args[1], sig.args[1])
        a2, b2, c2, _ = lw.load_plane(context, builder, sig.args[2], args[2], args[3], sig.args[3])
        zero = ir.Constant(M, 0)
        # The z component first: for planes that are not parallel it is almost always non-zero,
        # and the other two products are skipped.
        result = cgutils.alloca_once_value(builder, ir.Constant(ir.IntType(1), 0))
        z = lw.det2(builder, a1, b1, a2, b2, M)
        with builder.if_then(builder.icmp_signed("==", z, zero), likely=False):
            x = lw.det2(builder, b1, c1, b2, c2, M)
            y = lw.det2(builder, c1, a1, c2, a2, M)
            builder.store(builder.and_(builder.icmp_signed("==", x, zero), builder.icmp_signed("==", y, zero)), result)
        return builder.load(result)

    return types.boolean(P, i, Q, j), codegen


@intrinsic
def points_equal_at(typingctx, X, i, Y, j):
    """Whether homogeneous points ``X[i]`` and ``Y[j]`` are the same point: x_k y4 = y_k x4.

    Products are formed at twice the width, so any two wide points compare exactly.
    Both w components must be non-zero (finite points).
    """
    bits = lw.same_width("points_equal_at", X, Y)
    T = _T(bits)
    T2 = _T(2 * bits)

    def codegen(context, builder, sig, args):
        x = lw.load_row(context, builder, sig.args[0], args[0], args[1], sig.args[1], T, 4)
        y = lw.load_row(context, builder, sig.args[2], args[2], args[3], sig.args[3], T, 4)
        result = ir.Constant(ir.IntType(1), 1)
        for k in range(3):
            lhs = lw.mul_exact(builder, x[k], y[3], T2)
            rhs = lw.mul_exact(builder, y[k], x[3], T2)
            result = builder.and_(result, builder.icmp_signed("==", lhs, rhs))
        return result

    return types.boolean(X, i, Y, j), codegen


@intrinsic
def compare_plane_values_at(typingctx, X, iu, iv, S, j):
    """Sign of f(u) - f(v) where f(x) = (x·s) / x4 for points ``X[iu]``, ``X[iv]`` and plane ``S[j]``.

    f is the plane's signed distance times |n| at the Cartesian point, so this
    orders two homogeneous points by distance to the plane -- what edge descent
    needs. The dot products are final values bounded by the classification budget;
    the cross products ``(x_u·s)·x4_v`` are formed at twice the width. Returns int8.
    """
    bits = lw.same_width("compare_plane_values_at", X, S)
    T = _T(bits)
    T2 = _T(2 * bits)

    def codegen(context, builder, sig, args):
        xu = lw.load_row(context, builder, sig.args[0], args[0], args[1], sig.args[1], T, 4)
        xv = lw.load_row(context, builder, sig.args[0], args[0], args[2], sig.args[2], T, 4)
        s = lw.load_plane(context, builder, sig.args[3], args[3], args[4], sig.args[4])
        du = lw.dot(builder, xu, s, T)
        dv = lw.dot(builder, xv, s, T)
        return lw.exact_quotient_difference_sign(builder, du, xu[3], dv, xv[3], T2)

    return types.int8(X, iu, iv, S, j), codegen


#: Widths from which :func:`compare_cached_values_at` and :func:`compare_filtered_values_at` ask doubles first
#: (:func:`lowering.quotient_difference_sign`).
FILTER_COMPARISONS_FROM_BITS = 128


@intrinsic
def compare_cached_values_at(typingctx, D, iu, iv, X):
    """Sign of D[iu]/X[iu, 3] - D[iv]/X[iv, 3]: :func:`compare_plane_values_at` from stored dot products.

    ``D`` is a 1-D wide array of dot products x·s; products at twice the width. (The cut keeps doubles instead:
    :func:`compare_filtered_values_at`.)
    """
    bits = lw.same_width("compare_cached_values_at", D, X)
    T = _T(bits)
    T2 = _T(2 * bits)

    def codegen(context, builder, sig, args):
        du = lw.load_row(context, builder, sig.args[0], args[0], args[1], sig.args[1], T, 1)[0]
        dv = lw.load_row(context, builder, sig.args[0], args[0], args[2], sig.args[2], T, 1)[0]
        base_u = lw.row_pointer(context, builder, sig.args[3], args[3], args[1], sig.args[1])
        base_v = lw.row_pointer(context, builder, sig.args[3], args[3], args[2], sig.args[2])
        wu = lw.load(builder, base_u, 3, T)
        wv = lw.load(builder, base_v, 3, T)

        def exact(builder):
            return lw.exact_quotient_difference_sign(builder, du, wu, dv, wv, T2)

        if bits < FILTER_COMPARISONS_FROM_BITS:
            return exact(builder)
        # The cut's edge descent compares neighbours that are rarely close: doubles decide almost all of them, the
        # products at twice the width (i512 at 256 bits) only the close calls.
        return lw.quotient_difference_sign(builder, du, wu, dv, wv, exact)

    return types.int8(D, iu, iv, X), codegen


def _float_pair_pointers(context, builder, aty, aval, row, row_ty):
    """Pointers to F[row, 0] and F[row, 1] of a C-contiguous (n, 2) float64 array."""
    base = builder.bitcast(lw.row_pointer(context, builder, aty, aval, row, row_ty), F64.as_pointer())
    return base, builder.gep(base, [ir.Constant(I64, 1)])


def _filter_doubles_array(F, name):
    if not (isinstance(F, types.Array) and F.dtype == types.float64 and F.ndim == 2 and F.layout == "C"):
        raise TypingError(f"{name}: expected a C-contiguous (n, 2) float64 array of filter doubles, got {F}")


@intrinsic
def plane_value_filtered_into(typingctx, X, i, S, j, F):
    """The side of ``X[i]`` against ``S[j]`` (as :func:`classify_at`), keeping ``F[i] = (d, w)``: the filter doubles
    (:func:`csgnb.exact.lowering.filter_double`) of x·s and of x4.

    ``F`` is a C-contiguous (n, 2) float64 array beside ``X``; :func:`compare_filtered_values_at` reads it instead of
    converting wide values again at every comparison (doubles are written only from
    :data:`FILTER_COMPARISONS_FROM_BITS`, the widths that compare through them).
    """
    bits = lw.same_width("plane_value_filtered_into", X, S)
    T = _T(bits)
    _filter_doubles_array(F, "plane_value_filtered_into")

    def codegen(context, builder, sig, args):
        x = lw.load_row(context, builder, sig.args[0], args[0], args[1], sig.args[1], T, 4)
        s = lw.load_plane(context, builder, sig.args[2], args[2], args[3], sig.args[3])
        value = lw.plane_dot(builder, x, s, T)
        if bits >= FILTER_COMPARISONS_FROM_BITS:
            pd, pw = _float_pair_pointers(context, builder, sig.args[4], args[4], args[1], sig.args[1])
            builder.store(lw.filter_double(builder, value), pd, align=8)
            builder.store(lw.filter_double(builder, x[3]), pw, align=8)
        return lw.sign_times_sign(builder, value, x[3])

    return types.int8(X, i, S, j, F), codegen


@intrinsic
def compare_filtered_values_at(typingctx, F, iu, iv, X, S, j):
    """Sign of (x_u·s)/x_u4 - (x_v·s)/x_v4 for ``X[iu]``, ``X[iv]`` and plane ``S[j]``, from the filter doubles
    :func:`plane_value_filtered_into` kept in ``F``.

    Decided as :func:`compare_cached_values_at` decides it -- the same doubles, the same bound
    (:func:`csgnb.exact.lowering.quotient_difference_sign`) -- and a close call forms both dot products again and
    the cross products at twice the width: no wide value is kept per vertex for the rare close call.
    """
    bits = lw.same_width("compare_filtered_values_at", X, S)
    T = _T(bits)
    T2 = _T(2 * bits)
    _filter_doubles_array(F, "compare_filtered_values_at")

    def codegen(context, builder, sig, args):
        def exact(builder):
            xu = lw.load_row(context, builder, sig.args[3], args[3], args[1], sig.args[1], T, 4)
            xv = lw.load_row(context, builder, sig.args[3], args[3], args[2], sig.args[2], T, 4)
            s = lw.load_plane(context, builder, sig.args[4], args[4], args[5], sig.args[5])
            du, dv = lw.plane_dot(builder, xu, s, T), lw.plane_dot(builder, xv, s, T)
            return lw.exact_quotient_difference_sign(builder, du, xu[3], dv, xv[3], T2)

        if bits < FILTER_COMPARISONS_FROM_BITS:
            return exact(builder)
        pdu, pwu = _float_pair_pointers(context, builder, sig.args[0], args[0], args[1], sig.args[1])
        pdv, pwv = _float_pair_pointers(context, builder, sig.args[0], args[0], args[2], sig.args[2])
        fdu, fwu, fdv, fwv = (builder.load(p, align=8) for p in (pdu, pwu, pdv, pwv))
        return lw.quotient_difference_sign_of_doubles(builder, fdu, fwu, fdv, fwv, exact)

    return types.int8(F, iu, iv, X, S, j), codegen


# ---------------------------------------------------------------------------
# single-value helpers


def _element_intrinsic(name, result_type, body):
    """An intrinsic ``f(arr, i, j)`` reading element ``[i, j]`` of a 2-D (or ``[i]`` of a 1-D) wide array."""

    def typer(typingctx, arr, i, j):
        T = _T(lw.wide_width(arr, name))

        def codegen(context, builder, sig, args):
            base = lw.row_pointer(context, builder, sig.args[0], args[0], args[1], sig.args[1])
            col = context.cast(builder, args[2], sig.args[2], types.intp)
            return body(context, builder, lw.load(builder, base, col, T))

        return result_type(arr, i, j), codegen

    typer.__name__ = name
    return intrinsic(typer)


wide_sign_at = _element_intrinsic("wide_sign_at", types.int8, lambda ctx, b, v: lw.sign(b, v))
wide_sign_at.__doc__ = "int8 sign of the wide element ``arr[i, j]``."

wide_to_float_at = _element_intrinsic("wide_to_float_at", types.float64, lambda ctx, b, v: lw.to_double(b, v))
wide_to_float_at.__doc__ = "The wide element ``arr[i, j]`` rounded to the nearest double."

wide_filter_double_at = _element_intrinsic("wide_filter_double_at", types.float64,
                                           lambda ctx, b, v: lw.filter_double(b, v))
wide_filter_double_at.__doc__ = """A double within 4.001 units of 2**-53 (relative) of ``arr[i, j]``: cheap, for filters
(:func:`csgnb.exact.lowering.filter_double`; :func:`wide_to_float_at` rounds correctly, at several times the cost)."""

wide_to_int64_at = _element_intrinsic("wide_to_int64_at", types.int64, lambda ctx, b, v: b.trunc(v, I64))
wide_to_int64_at.__doc__ = "The low 64 bits of ``arr[i, j]`` as int64 (exact when it fits)."


def _split(ctx, builder, v):
    hi, lo = lw.split_double(builder, v)
    return ctx.make_tuple(builder, types.UniTuple(types.float64, 2), [hi, lo])


wide_split_double_at = _element_intrinsic("wide_split_double_at", types.UniTuple(types.float64, 2), _split)
wide_split_double_at.__doc__ = (
    "(hi, lo): |arr[i, j]| truncated to 106 bits as two exact doubles, hi the top 53 bits, lo the next 53 "
    "(0 <= |v| - hi - lo < 2**-105 |v|).")


@intrinsic
def wide_abs_greater_at(typingctx, A, i, j, B, k, m):
    """Whether ``|A[i, j]| > |B[k, m]|`` (exact, also for the most negative value)."""
    T = _T(lw.same_width("wide_abs_greater_at", A, B))

    def codegen(context, builder, sig, args):
        def load(aty, aval, row, row_ty, col, col_ty):
            base = lw.row_pointer(context, builder, aty, aval, row, row_ty)
            return lw.load(builder, base, context.cast(builder, col, col_ty, types.intp), T)

        a = load(sig.args[0], args[0], args[1], sig.args[1], args[2], sig.args[2])
        b = load(sig.args[3], args[3], args[4], sig.args[4], args[5], sig.args[5])
        return builder.icmp_unsigned(">", lw.absolute(builder, a), lw.absolute(builder, b))

    return types.boolean(A, i, j, B, k, m), codegen


@intrinsic
def wide_divexact_at(typingctx, arr, i, j, g):
    """Divide ``arr[i, j]`` in place by the int64 ``g`` (the division must be exact)."""
    T = _T(lw.wide_width(arr, "wide_divexact_at"))

    def codegen(context, builder, sig, args):
        base = lw.row_pointer(context, builder, sig.args[0], args[0], args[1], sig.args[1])
        ptr = lw.element_pointer(builder, base, context.cast(builder, args[2], sig.args[2], types.intp), T)
        divisor = context.cast(builder, args[3], sig.args[3], types.int64)
        builder.store(lw.divexact(builder, builder.load(ptr, align=8), divisor), ptr, align=8)
        return context.get_dummy_value()

    return types.none(arr, i, j, g), codegen


@intrinsic
def compare_ratio_dyadic_at(typingctx, X, i, jn, jd, M, E):
    """Sign of ``|X[i, jn]| - |X[i, jd]| * M * 2**E`` for int64 ``M >= 0`` and int64 ``E``.

    Computed exactly at twice the width: the exact rounding step of
    :func:`csgnb.exact.predicates.to_double_position` compares the rational
    ``x_jn / x_jd`` with the dyadic midpoints between adjacent doubles. Shifts are
    clamped to the double width, which callers keep far away from.
    """
    bits = lw.wide_width(X, "compare_ratio_dyadic_at")
    T = _T(bits)
    T2 = _T(2 * bits)

    def codegen(context, builder, sig, args):
        base = lw.row_pointer(context, builder, sig.args[0], args[0], args[1], sig.args[1])
        jn = context.cast(builder, args[2], sig.args[2], types.intp)
        jd = context.cast(builder, args[3], sig.args[3], types.intp)
        num = builder.zext(lw.absolute(builder, lw.load(builder, base, jn, T)), T2)
        den = builder.zext(lw.absolute(builder, lw.load(builder, base, jd, T)), T2)
        m = builder.zext(context.cast(builder, args[4], sig.args[4], types.int64), T2)
        e = context.cast(builder, args[5], sig.args[5], types.int64)
        rhs = builder.mul(den, m)
        limit = ir.Constant(I64, 2 * bits - 1)
        zero64 = ir.Constant(I64, 0)

        # E >= 0: shift the right side up; E < 0: shift the numerator up instead.
        def clamp(amount):
            amount = builder.select(builder.icmp_signed("<", amount, zero64), zero64, amount)
            return builder.select(builder.icmp_signed(">", amount, limit), limit, amount)

        up = clamp(e)
        down = clamp(builder.neg(e))
        nonneg = builder.icmp_signed(">=", e, zero64)
        lhs = builder.select(nonneg, num, builder.shl(num, builder.zext(down, T2)))
        rhs = builder.select(nonneg, builder.shl(rhs, builder.zext(up, T2)), rhs)
        gt = builder.zext(builder.icmp_unsigned(">", lhs, rhs), I8)
        lt = builder.zext(builder.icmp_unsigned("<", lhs, rhs), I8)
        return builder.sub(gt, lt)

    return types.int8(X, i, jn, jd, M, E), codegen


@intrinsic
def scan_rows(typingctx, arr, start, stop, acc):
    """Fold rows ``[start, stop)`` of ``arr`` into ``acc`` (see :class:`csgnb.exact.lowering.Scan`).

    ``arr`` is an ``(n, 4)`` wide array (planes or points) or narrow planes, with ``acc``
    ``(4k + 2,) uint64`` (k = width / 64): per-(column, limb) maxima of one's-complement
    magnitudes and the zero-normal / zero-x4 flags; or ``(n, 3) int64`` points with ``acc``
    ``(2,) int64`` = [max, min].
    """
    if isinstance(arr, types.Array) and arr.dtype == types.int64:
        lw.int_array(arr, "scan_rows")
        want = types.int64
    else:
        lw.plane_layout(arr, "scan_rows")
        want = types.uint64
    if not (isinstance(acc, types.Array) and acc.dtype == want and acc.layout == "C" and acc.ndim == 1):
        raise TypingError(f"scan_rows: acc must be a C-contiguous 1-D {want} array, got {acc}")

    def codegen(context, builder, sig, args):
        lo = context.cast(builder, args[1], sig.args[1], types.int64)
        hi = context.cast(builder, args[2], sig.args[2], types.int64)
        lw.scan_rows(context, builder, sig.args[0], args[0], sig.args[3], args[3], lo, hi)
        return context.get_dummy_value()

    return types.none(arr, start, stop, acc), codegen


@intrinsic
def positions_into(typingctx, X, i, out, io):
    """Store x_c / x4 of the point ``X[i]`` into ``out[io, 0:3]`` (float64); return the certified lanes (int8 bits).

    All three quotients at once in 4-lane vectors (x4 in the fourth): a truncated double-double
    split, one reciprocal and an FMA-exact residual per lane, certified against the midpoints
    with the relative error bound :data:`csgnb.exact.lowering.CERTIFY` (see
    :func:`csgnb.exact.predicates._positions` for its derivation).
    Bit c of the result is set when out[io, c] is the correctly rounded quotient; the caller
    recomputes the other lanes exactly. ``X[i, 3]`` must not be zero.
    """
    k = lw.wide_width(X, "positions_into") // 64

    def codegen(context, builder, sig, args):
        base = lw.row_pointer(context, builder, sig.args[0], args[0], args[1], sig.args[1])
        V4k = ir.VectorType(I64, 4 * k)
        row = builder.load(builder.bitcast(base, V4k.as_pointer()), align=8)
        limbs = [builder.shuffle_vector(row, row, ir.Constant(ir.VectorType(ir.IntType(32), 4),
                                                              [c * k + j for c in range(4)])) for j in range(k)]
        values, mask = lw.certified_quotients(builder, limbs, k, lw.CERTIFY)
        out_base = lw.row_pointer(context, builder, sig.args[2], args[2], args[3], sig.args[3])
        for c in range(3):
            ptr = builder.bitcast(builder.gep(out_base, [ir.Constant(I64, 8 * c)]), F64.as_pointer())
            builder.store(builder.extract_element(values, ir.Constant(ir.IntType(32), c)), ptr)
        return mask

    return types.int8(X, i, out, io), codegen


@intrinsic
def trailing_zeros(typingctx, x):
    """Number of trailing zero bits of the int64 ``x`` (64 for 0): ``llvm.cttz``."""
    if x != types.int64:
        raise TypingError(f"trailing_zeros: expected int64, got {x}")

    def codegen(context, builder, sig, args):
        f = lw.bit_count_intrinsic(builder, "llvm.cttz", I64)
        return builder.call(f, [args[0], ir.Constant(ir.IntType(1), 0)])

    return types.int64(x), codegen


@intrinsic
def cross_sign(typingctx, a, b, c, d):
    """Sign (-1, 0, 1) of ``a·b - c·d`` for int64 operands, computed in ``i128``: exact for every int64 input
    (each product is below 2**126 in magnitude, their difference below 2**127)."""
    if not (a == b == c == d == types.int64):
        raise TypingError(f"cross_sign: expected four int64, got {a}, {b}, {c}, {d}")

    def codegen(context, builder, sig, args):
        T = _T(128)
        x, y, z, w = (builder.sext(v, T) for v in args)
        value = builder.sub(builder.mul(x, y), builder.mul(z, w))
        zero = ir.Constant(T, 0)
        pos = builder.zext(builder.icmp_signed(">", value, zero), I64)
        neg = builder.zext(builder.icmp_signed("<", value, zero), I64)
        return builder.sub(pos, neg)

    return types.int64(a, b, c, d), codegen


@intrinsic
def plane_side_sign(typingctx, n0, n1, n2, x0, x1, x2, dh, dl):
    """Sign (-1, 0, 1) of ``n·x + dh·2**62 + dl`` for int64 operands, computed in ``i128``: exact when
    ``|n·x| < 2**125`` and ``|dh·2**62 + dl| < 2**125`` (a plane offset split into a high and a low part)."""
    if not all(t == types.int64 for t in (n0, n1, n2, x0, x1, x2, dh, dl)):
        raise TypingError("plane_side_sign: expected eight int64")

    def codegen(context, builder, sig, args):
        T = _T(128)
        a0, a1, a2, b0, b1, b2, h, lo = (builder.sext(v, T) for v in args)
        value = builder.add(builder.mul(a0, b0), builder.mul(a1, b1))
        value = builder.add(value, builder.mul(a2, b2))
        value = builder.add(value, builder.add(builder.shl(h, ir.Constant(T, 62)), lo))
        zero = ir.Constant(T, 0)
        pos = builder.zext(builder.icmp_signed(">", value, zero), I64)
        neg = builder.zext(builder.icmp_signed("<", value, zero), I64)
        return builder.sub(pos, neg)

    return types.int64(n0, n1, n2, x0, x1, x2, dh, dl), codegen


@intrinsic
def fma(typingctx, a, b, c):
    """a * b + c with a single rounding (``llvm.fma.f64``; one instruction on x86-64 with FMA)."""
    if not (a == b == c == types.float64):
        raise TypingError(f"fma: expected three float64, got {a}, {b}, {c}")

    def codegen(context, builder, sig, args):
        f = builder.module.declare_intrinsic("llvm.fma", [F64], ir.FunctionType(F64, [F64, F64, F64]))
        return builder.call(f, list(args))

    return types.float64(a, b, c), codegen


@intrinsic
def half_ulp(typingctx, x):
    """(up, down) for a positive normal double ``x``: half the gap to the next double above and below.

    ``down`` is half of ``up`` when ``x`` is a power of two (the gap below is half as wide).
    Built from the IEEE bits: exact, no division, no libm call.
    """
    if x != types.float64:
        raise TypingError(f"half_ulp: expected float64, got {x}")

    def codegen(context, builder, sig, args):
        bits = builder.bitcast(args[0], I64)
        exponent = builder.and_(bits, ir.Constant(I64, 0x7FF << 52))
        up = builder.bitcast(builder.sub(exponent, ir.Constant(I64, 53 << 52)), F64)  # 2**(e - 53)
        mantissa = builder.and_(bits, ir.Constant(I64, (1 << 52) - 1))
        pow2 = builder.icmp_unsigned("==", mantissa, ir.Constant(I64, 0))
        down = builder.select(pow2, builder.fmul(up, ir.Constant(F64, 0.5)), up)
        return context.make_tuple(builder, types.UniTuple(types.float64, 2), [up, down])

    return types.UniTuple(types.float64, 2)(x), codegen

