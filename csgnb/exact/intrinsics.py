"""LLVM wide-integer intrinsics: the exact arithmetic under every predicate.

numba has no integer type wider than 64 bits, but LLVM has ``i128``, ``i192``,
``i256`` and ``i512``, and lowers their ``add``/``mul``/``shl`` to chains of
``adc``/``mulx`` on x86-64 -- the same instruction sequences the paper's C++
builds by hand. Each intrinsic here reads whole wide elements straight from a
C-contiguous wide array (see :mod:`csgnb.exact.wide`), computes in LLVM's native
wide integers and returns a small result (a sign, a bool, a double) or stores
wide values into an output array.

The width is read from the array's record dtype at typing time, so one jitted
kernel compiles to a 128-, 192- and 256-bit version on demand, each cached.

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

__all__ = [
    "classify_at",
    "intersect_into",
    "plane_from_points_into",
    "signed_distance_into",
    "planes_parallel_at",
    "points_equal_at",
    "compare_plane_values_at",
    "plane_value_into",
    "compare_cached_values_at",
    "wide_sign_at",
    "wide_to_float_at",
    "wide_to_int64_at",
    "wide_abs_greater_at",
    "wide_divexact_at",
    "compare_ratio_dyadic_at",
]

_I8 = ir.IntType(8)
_I64 = ir.IntType(64)


# ---------------------------------------------------------------------------
# typing helpers


def _wide_width(aty, name: str) -> int:
    """Width in bits of a wide array type; a numba typing error otherwise."""
    if not (
        isinstance(aty, types.Array)
        and isinstance(aty.dtype, types.Record)
        and aty.dtype.size in (16, 24, 32)
        and aty.layout == "C"
    ):
        raise TypingError(f"{name}: expected a C-contiguous wide-integer array, got {aty}")
    return aty.dtype.size * 8


def _int_array(aty, name: str) -> None:
    if not (
        isinstance(aty, types.Array) and aty.dtype == types.int64 and aty.layout == "C"
    ):
        raise TypingError(f"{name}: expected a C-contiguous int64 array, got {aty}")


def _same_width(name: str, *atys) -> int:
    widths = {_wide_width(a, name) for a in atys}
    if len(widths) != 1:
        raise TypingError(f"{name}: operands have different widths {sorted(widths)}")
    return widths.pop()


# ---------------------------------------------------------------------------
# codegen helpers


def _row_pointer(context, builder, aty, aval, row, row_ty):
    """Byte pointer (i8*) to the first element of row ``row`` (or element ``row`` of a 1-D array)."""
    ary = context.make_array(aty)(context, builder, aval)
    row = context.cast(builder, row, row_ty, types.intp)
    index = [row] + [ir.Constant(_I64, 0)] * (aty.ndim - 1)
    ptr = cgutils.get_item_pointer(context, builder, aty, ary, index)
    return builder.bitcast(ptr, ir.IntType(8).as_pointer())


def _element_pointer(builder, base, col, T):
    """Pointer to column ``col`` (int or i64 value) of a row of ``T`` elements.

    Addressed in bytes: LLVM pads ``i192`` to a 32-byte allocation, so a typed
    GEP would stride past the 24-byte elements of a 192-bit array.
    """
    size = T.width // 8
    offset = ir.Constant(_I64, col * size) if isinstance(col, int) else builder.mul(col, ir.Constant(_I64, size))
    return builder.bitcast(builder.gep(base, [offset]), T.as_pointer())


def _load(builder, base, col, T):
    return builder.load(_element_pointer(builder, base, col, T), align=8)


def _load_row(context, builder, aty, aval, row, row_ty, T, ncols):
    """Load ``ncols`` values of a row as ``T`` integers (int64 rows are sign-extended)."""
    base = _row_pointer(context, builder, aty, aval, row, row_ty)
    if isinstance(aty.dtype, types.Record):
        return [_load(builder, base, c, T) for c in range(ncols)]
    return [builder.sext(_load(builder, base, c, _I64), T) for c in range(ncols)]


def _store_row(context, builder, aty, aval, row, row_ty, T, values):
    base = _row_pointer(context, builder, aty, aval, row, row_ty)
    for c, v in enumerate(values):
        builder.store(v, _element_pointer(builder, base, c, T), align=8)


def _sign(builder, v):
    """int8 sign (-1, 0, +1) of the signed integer ``v``."""
    zero = ir.Constant(v.type, 0)
    pos = builder.zext(builder.icmp_signed(">", v, zero), _I8)
    neg = builder.zext(builder.icmp_signed("<", v, zero), _I8)
    return builder.sub(pos, neg)


def _abs(builder, v):
    """|v| as an unsigned value of the same width (exact also for the minimum)."""
    neg = builder.icmp_signed("<", v, ir.Constant(v.type, 0))
    return builder.select(neg, builder.neg(v), v)


def _bit_count_intrinsic(builder, name, T):
    """Declare ``llvm.ctlz``/``llvm.cttz`` for ``T`` with both arguments (llvmlite omits the i1 flag)."""
    return builder.module.declare_intrinsic(name, [T], ir.FunctionType(T, [T, ir.IntType(1)]))


def _to_double(builder, v):
    """``v`` rounded to the nearest double (ties to even), without compiler-rt calls.

    LLVM lowers a 128-bit ``sitofp`` to ``__floattidf``, which numba cannot link,
    and folds widening tricks back to it; so: normalise |v| with ``ctlz``, keep
    the top 64 bits with a sticky bit for everything below (enough for correct
    rounding to 53 bits), convert those, and scale by an exact power of two.
    """
    T = v.type
    W = T.width
    magnitude = _abs(builder, v)
    ctlz = _bit_count_intrinsic(builder, "llvm.ctlz", T)
    lz = builder.call(ctlz, [magnitude, ir.Constant(ir.IntType(1), 0)])
    norm = builder.shl(magnitude, lz)
    top = builder.trunc(builder.lshr(norm, ir.Constant(T, W - 64)), _I64)
    sticky = builder.icmp_unsigned("!=", builder.trunc(norm, ir.IntType(W - 64)), ir.Constant(ir.IntType(W - 64), 0))
    top = builder.or_(top, builder.zext(sticky, _I64))
    f = builder.uitofp(top, ir.DoubleType())
    exponent = builder.sub(ir.Constant(_I64, W - 64), builder.trunc(lz, _I64))  # in [-63, W - 64]
    biased = builder.add(exponent, ir.Constant(_I64, 1023))  # 2**exponent built from its IEEE bits
    scale = builder.bitcast(builder.shl(biased, ir.Constant(_I64, 52)), ir.DoubleType())
    f = builder.fmul(f, scale)
    f = builder.select(builder.icmp_signed("<", v, ir.Constant(T, 0)), builder.fneg(f), f)
    return builder.select(builder.icmp_signed("==", v, ir.Constant(T, 0)), ir.Constant(ir.DoubleType(), 0.0), f)


def _divexact(builder, v, g):
    """``v / g`` for an int64 ``g != 0`` that divides ``v`` exactly, without a division.

    Exact division is an arithmetic shift by the twos in ``g`` followed by a
    multiplication with the inverse of its odd part modulo 2**W (Newton's
    iteration doubles the correct low bits each step, from 3).
    """
    T = v.type
    negative = builder.icmp_signed("<", g, ir.Constant(_I64, 0))
    g = builder.select(negative, builder.neg(g), g)
    twos = builder.call(_bit_count_intrinsic(builder, "llvm.cttz", _I64), [g, ir.Constant(ir.IntType(1), 1)])
    odd = builder.zext(builder.lshr(g, twos), T)
    shifted = builder.ashr(v, builder.zext(twos, T))
    inverse = odd
    two = ir.Constant(T, 2)
    for _ in range(max(1, (T.width // 3).bit_length())):
        inverse = builder.mul(inverse, builder.sub(two, builder.mul(odd, inverse)))
    q = builder.mul(shifted, inverse)
    return builder.select(negative, builder.neg(q), q)


def _det2(builder, a, b, c, d):
    """a*d - b*c."""
    return builder.sub(builder.mul(a, d), builder.mul(b, c))


def _dot(builder, xs, ys):
    acc = builder.mul(xs[0], ys[0])
    for x, y in zip(xs[1:], ys[1:], strict=True):
        acc = builder.add(acc, builder.mul(x, y))
    return acc


# ---------------------------------------------------------------------------
# predicates


@intrinsic
def classify_at(typingctx, points, i, planes, j):
    """Sign of point ``points[i]`` against plane ``planes[j]``: sign(x·s)·sign(x4) (eq. 6).

    ``points`` and ``planes`` are ``(n, 4)`` wide arrays of one width. Returns int8:
    +1 on the positive side, -1 on the negative side, 0 on the plane.
    """
    bits = _same_width("classify_at", points, planes)
    T = ir.IntType(bits)

    def codegen(context, builder, sig, args):
        pa, ia, la, ja = args
        x = _load_row(context, builder, sig.args[0], pa, ia, sig.args[1], T, 4)
        s = _load_row(context, builder, sig.args[2], la, ja, sig.args[3], T, 4)
        return builder.mul(_sign(builder, _dot(builder, x, s)), _sign(builder, x[3]))

    return types.int8(points, i, planes, j), codegen


@intrinsic
def intersect_into(typingctx, P, ip, Q, iq, R, ir_, out, io):
    """Store intersect(p, q, r) (eq. 5) of planes ``P[ip], Q[iq], R[ir_]`` into ``out[io]``.

    The homogeneous point is the vector of cofactors of the first row of
    ``det[e1 e2 e3 e4; p; q; r]``, so that ``x·s = det[s; p; q; r]`` for any plane
    ``s`` and ``x·p = x·q = x·r = 0``. ``x4 = -det(n_p, n_q, n_r)`` is zero when the
    normals are linearly dependent (no unique intersection).
    """
    bits = _same_width("intersect_into", P, Q, R, out)
    T = ir.IntType(bits)

    def codegen(context, builder, sig, args):
        a_p, b_p, c_p, d_p = _load_row(context, builder, sig.args[0], args[0], args[1], sig.args[1], T, 4)
        a_q, b_q, c_q, d_q = _load_row(context, builder, sig.args[2], args[2], args[3], sig.args[3], T, 4)
        a_r, b_r, c_r, d_r = _load_row(context, builder, sig.args[4], args[4], args[5], sig.args[5], T, 4)
        # 2x2 minors of the rows q, r, shared by the four 3x3 cofactors.
        m_ab = _det2(builder, a_q, b_q, a_r, b_r)
        m_ac = _det2(builder, a_q, c_q, a_r, c_r)
        m_ad = _det2(builder, a_q, d_q, a_r, d_r)
        m_bc = _det2(builder, b_q, c_q, b_r, c_r)
        m_bd = _det2(builder, b_q, d_q, b_r, d_r)
        m_cd = _det2(builder, c_q, d_q, c_r, d_r)
        det_bcd = _dot(builder, [b_p, c_p, d_p], [m_cd, builder.neg(m_bd), m_bc])
        det_acd = _dot(builder, [a_p, c_p, d_p], [m_cd, builder.neg(m_ad), m_ac])
        det_abd = _dot(builder, [a_p, b_p, d_p], [m_bd, builder.neg(m_ad), m_ab])
        det_abc = _dot(builder, [a_p, b_p, c_p], [m_bc, builder.neg(m_ac), m_ab])
        x = [det_bcd, builder.neg(det_acd), det_abd, builder.neg(det_abc)]
        _store_row(context, builder, sig.args[6], args[6], args[7], sig.args[7], T, x)
        return context.get_dummy_value()

    return types.none(P, ip, Q, iq, R, ir_, out, io), codegen


@intrinsic
def plane_from_points_into(typingctx, Pt, ip, Qt, iq, Rt, ir_, out, io):
    """Store the plane through integer points ``Pt[ip], Qt[iq], Rt[ir_]`` into ``out[io]``.

    ``n = (q - p) x (r - p)``, ``d = -n·p``; the points are ``(n, 3) int64`` rows and
    all arithmetic is done at the width of ``out``. The normal is zero for
    collinear points.
    """
    for a in (Pt, Qt, Rt):
        _int_array(a, "plane_from_points_into")
    bits = _wide_width(out, "plane_from_points_into")
    T = ir.IntType(bits)

    def codegen(context, builder, sig, args):
        p = _load_row(context, builder, sig.args[0], args[0], args[1], sig.args[1], T, 3)
        q = _load_row(context, builder, sig.args[2], args[2], args[3], sig.args[3], T, 3)
        r = _load_row(context, builder, sig.args[4], args[4], args[5], sig.args[5], T, 3)
        e1 = [builder.sub(qi, pi) for qi, pi in zip(q, p, strict=True)]
        e2 = [builder.sub(ri, pi) for ri, pi in zip(r, p, strict=True)]
        n = [
            _det2(builder, e1[1], e1[2], e2[1], e2[2]),
            _det2(builder, e1[2], e1[0], e2[2], e2[0]),
            _det2(builder, e1[0], e1[1], e2[0], e2[1]),
        ]
        d = builder.neg(_dot(builder, n, p))
        _store_row(context, builder, sig.args[6], args[6], args[7], sig.args[7], T, n + [d])
        return context.get_dummy_value()

    return types.none(Pt, ip, Qt, iq, Rt, ir_, out, io), codegen


@intrinsic
def signed_distance_into(typingctx, pts, i, planes, j, out, io):
    """Store ``n·v + d`` of integer point ``pts[i]`` ((n, 3) int64) and plane ``planes[j]`` into ``out[io]``.

    The value is the signed distance scaled by |n| (exact, no division).
    """
    _int_array(pts, "signed_distance_into")
    bits = _same_width("signed_distance_into", planes, out)
    T = ir.IntType(bits)

    def codegen(context, builder, sig, args):
        v = _load_row(context, builder, sig.args[0], args[0], args[1], sig.args[1], T, 3)
        s = _load_row(context, builder, sig.args[2], args[2], args[3], sig.args[3], T, 4)
        value = builder.add(_dot(builder, v, s[:3]), s[3])
        _store_row(context, builder, sig.args[4], args[4], args[5], sig.args[5], T, [value])
        return context.get_dummy_value()

    return types.none(pts, i, planes, j, out, io), codegen


@intrinsic
def planes_parallel_at(typingctx, P, i, Q, j):
    """Whether the normals of ``P[i]`` and ``Q[j]`` are parallel: n_p x n_q = 0 (eq. 1)."""
    bits = _same_width("planes_parallel_at", P, Q)
    T = ir.IntType(bits)

    def codegen(context, builder, sig, args):
        a1, b1, c1 = _load_row(context, builder, sig.args[0], args[0], args[1], sig.args[1], T, 3)
        a2, b2, c2 = _load_row(context, builder, sig.args[2], args[2], args[3], sig.args[3], T, 3)
        zero = ir.Constant(T, 0)
        cross = [_det2(builder, b1, c1, b2, c2), _det2(builder, c1, a1, c2, a2), _det2(builder, a1, b1, a2, b2)]
        result = builder.icmp_signed("==", cross[0], zero)
        for c in cross[1:]:
            result = builder.and_(result, builder.icmp_signed("==", c, zero))
        return result

    return types.boolean(P, i, Q, j), codegen


@intrinsic
def points_equal_at(typingctx, X, i, Y, j):
    """Whether homogeneous points ``X[i]`` and ``Y[j]`` are the same point: x_k y4 = y_k x4.

    Products are formed at twice the width, so any two wide points compare exactly.
    Both w components must be non-zero (finite points).
    """
    bits = _same_width("points_equal_at", X, Y)
    T = ir.IntType(bits)
    T2 = ir.IntType(2 * bits)

    def codegen(context, builder, sig, args):
        x = [builder.sext(v, T2) for v in _load_row(context, builder, sig.args[0], args[0], args[1], sig.args[1], T, 4)]
        y = [builder.sext(v, T2) for v in _load_row(context, builder, sig.args[2], args[2], args[3], sig.args[3], T, 4)]
        result = ir.Constant(ir.IntType(1), 1)
        for k in range(3):
            lhs = builder.mul(x[k], y[3])
            rhs = builder.mul(y[k], x[3])
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
    bits = _same_width("compare_plane_values_at", X, S)
    T = ir.IntType(bits)
    T2 = ir.IntType(2 * bits)

    def codegen(context, builder, sig, args):
        xu = _load_row(context, builder, sig.args[0], args[0], args[1], sig.args[1], T, 4)
        xv = _load_row(context, builder, sig.args[0], args[0], args[2], sig.args[2], T, 4)
        s = _load_row(context, builder, sig.args[3], args[3], args[4], sig.args[4], T, 4)
        du = builder.sext(_dot(builder, xu, s), T2)
        dv = builder.sext(_dot(builder, xv, s), T2)
        diff = builder.sub(builder.mul(du, builder.sext(xv[3], T2)), builder.mul(dv, builder.sext(xu[3], T2)))
        return builder.mul(builder.mul(_sign(builder, diff), _sign(builder, xu[3])), _sign(builder, xv[3]))

    return types.int8(X, iu, iv, S, j), codegen


@intrinsic
def plane_value_into(typingctx, X, i, S, j, out, io):
    """Store x·s of point ``X[i]`` and plane ``S[j]`` into the 1-D wide ``out[io]``; return the side.

    The side is sign(x·s)·sign(x4) as in :func:`classify_at`; keeping x·s lets later
    distance comparisons (:func:`compare_cached_values_at`) skip the dot product.
    """
    bits = _same_width("plane_value_into", X, S, out)
    T = ir.IntType(bits)

    def codegen(context, builder, sig, args):
        x = _load_row(context, builder, sig.args[0], args[0], args[1], sig.args[1], T, 4)
        s = _load_row(context, builder, sig.args[2], args[2], args[3], sig.args[3], T, 4)
        dot = _dot(builder, x, s)
        _store_row(context, builder, sig.args[4], args[4], args[5], sig.args[5], T, [dot])
        return builder.mul(_sign(builder, dot), _sign(builder, x[3]))

    return types.int8(X, i, S, j, out, io), codegen


@intrinsic
def compare_cached_values_at(typingctx, D, iu, iv, X):
    """Sign of D[iu]/X[iu, 3] - D[iv]/X[iv, 3]: :func:`compare_plane_values_at` from stored dot products.

    ``D`` is the 1-D wide array :func:`plane_value_into` filled; products at twice the width.
    """
    bits = _same_width("compare_cached_values_at", D, X)
    T = ir.IntType(bits)
    T2 = ir.IntType(2 * bits)

    def codegen(context, builder, sig, args):
        du = _load_row(context, builder, sig.args[0], args[0], args[1], sig.args[1], T, 1)[0]
        dv = _load_row(context, builder, sig.args[0], args[0], args[2], sig.args[2], T, 1)[0]
        base_u = _row_pointer(context, builder, sig.args[3], args[3], args[1], sig.args[1])
        base_v = _row_pointer(context, builder, sig.args[3], args[3], args[2], sig.args[2])
        wu = _load(builder, base_u, 3, T)
        wv = _load(builder, base_v, 3, T)
        diff = builder.sub(builder.mul(builder.sext(du, T2), builder.sext(wv, T2)),
                           builder.mul(builder.sext(dv, T2), builder.sext(wu, T2)))
        return builder.mul(builder.mul(_sign(builder, diff), _sign(builder, wu)), _sign(builder, wv))

    return types.int8(D, iu, iv, X), codegen


# ---------------------------------------------------------------------------
# single-value helpers


def _element_intrinsic(name, result_type, body):
    """An intrinsic ``f(arr, i, j)`` reading element ``[i, j]`` of a 2-D (or ``[i]`` of a 1-D) wide array."""

    def typer(typingctx, arr, i, j):
        bits = _wide_width(arr, name)
        T = ir.IntType(bits)

        def codegen(context, builder, sig, args):
            base = _row_pointer(context, builder, sig.args[0], args[0], args[1], sig.args[1])
            col = context.cast(builder, args[2], sig.args[2], types.intp)
            return body(context, builder, _load(builder, base, col, T))

        return result_type(arr, i, j), codegen

    typer.__name__ = name
    return intrinsic(typer)


wide_sign_at = _element_intrinsic("wide_sign_at", types.int8, lambda ctx, b, v: _sign(b, v))
wide_sign_at.__doc__ = "int8 sign of the wide element ``arr[i, j]``."

wide_to_float_at = _element_intrinsic(
    "wide_to_float_at", types.float64, lambda ctx, b, v: _to_double(b, v)
)
wide_to_float_at.__doc__ = "The wide element ``arr[i, j]`` rounded to the nearest double."

wide_to_int64_at = _element_intrinsic("wide_to_int64_at", types.int64, lambda ctx, b, v: b.trunc(v, _I64))
wide_to_int64_at.__doc__ = "The low 64 bits of ``arr[i, j]`` as int64 (exact when it fits)."


@intrinsic
def wide_abs_greater_at(typingctx, A, i, j, B, k, m):
    """Whether ``|A[i, j]| > |B[k, m]|`` (exact, also for the most negative value)."""
    bits = _same_width("wide_abs_greater_at", A, B)
    T = ir.IntType(bits)

    def codegen(context, builder, sig, args):
        def load(aty, aval, row, row_ty, col, col_ty):
            base = _row_pointer(context, builder, aty, aval, row, row_ty)
            return _load(builder, base, context.cast(builder, col, col_ty, types.intp), T)

        a = load(sig.args[0], args[0], args[1], sig.args[1], args[2], sig.args[2])
        b = load(sig.args[3], args[3], args[4], sig.args[4], args[5], sig.args[5])
        return builder.icmp_unsigned(">", _abs(builder, a), _abs(builder, b))

    return types.boolean(A, i, j, B, k, m), codegen


@intrinsic
def wide_divexact_at(typingctx, arr, i, j, g):
    """Divide ``arr[i, j]`` in place by the int64 ``g`` (the division must be exact)."""
    bits = _wide_width(arr, "wide_divexact_at")
    T = ir.IntType(bits)

    def codegen(context, builder, sig, args):
        base = _row_pointer(context, builder, sig.args[0], args[0], args[1], sig.args[1])
        ptr = _element_pointer(builder, base, context.cast(builder, args[2], sig.args[2], types.intp), T)
        divisor = context.cast(builder, args[3], sig.args[3], types.int64)
        builder.store(_divexact(builder, builder.load(ptr, align=8), divisor), ptr, align=8)
        return context.get_dummy_value()

    return types.none(arr, i, j, g), codegen


@intrinsic
def compare_ratio_dyadic_at(typingctx, X, i, jn, jd, M, E):
    """Sign of ``|X[i, jn]| - |X[i, jd]| * M * 2**E`` for int64 ``M >= 0`` and int64 ``E``.

    Computed exactly at twice the width: the rounding step of
    :func:`csgnb.exact.predicates.to_double_position` compares the rational
    ``x_jn / x_jd`` with the dyadic midpoints between adjacent doubles. Shifts are
    clamped to the double width, which callers keep far away from.
    """
    bits = _wide_width(X, "compare_ratio_dyadic_at")
    T = ir.IntType(bits)
    T2 = ir.IntType(2 * bits)

    def codegen(context, builder, sig, args):
        base = _row_pointer(context, builder, sig.args[0], args[0], args[1], sig.args[1])
        jn = context.cast(builder, args[2], sig.args[2], types.intp)
        jd = context.cast(builder, args[3], sig.args[3], types.intp)
        num = builder.zext(_abs(builder, _load(builder, base, jn, T)), T2)
        den = builder.zext(_abs(builder, _load(builder, base, jd, T)), T2)
        m = builder.zext(context.cast(builder, args[4], sig.args[4], types.int64), T2)
        e = context.cast(builder, args[5], sig.args[5], types.int64)
        rhs = builder.mul(den, m)
        limit = ir.Constant(_I64, 2 * bits - 1)
        zero64 = ir.Constant(_I64, 0)
        # E >= 0: shift the right side up; E < 0: shift the numerator up instead.
        def clamp(amount):
            amount = builder.select(builder.icmp_signed("<", amount, zero64), zero64, amount)
            return builder.select(builder.icmp_signed(">", amount, limit), limit, amount)

        up = clamp(e)
        down = clamp(builder.neg(e))
        nonneg = builder.icmp_signed(">=", e, zero64)
        lhs = builder.select(nonneg, num, builder.shl(num, builder.zext(down, T2)))
        rhs = builder.select(nonneg, builder.shl(rhs, builder.zext(up, T2)), rhs)
        gt = builder.zext(builder.icmp_unsigned(">", lhs, rhs), _I8)
        lt = builder.zext(builder.icmp_unsigned("<", lhs, rhs), _I8)
        return builder.sub(gt, lt)

    return types.int8(X, i, jn, jd, M, E), codegen
