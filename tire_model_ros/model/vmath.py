"""Branch-free double-precision sin, cos, tan, atan, exp, log and pow that LLVM can vectorise.

numba calls libm for ``math.atan`` & co.; a libm call has no vector form here (the llvmlite
wheels are built without SVML), so a sample loop that calls it runs one sample at a time. These
functions are plain arithmetic and selects: inlined into a loop, LLVM turns them into SIMD code,
and they need no library at all.

Method: argument reduction, then a polynomial on the reduced interval (fdlibm's minimax
coefficients for sin, cos, atan and log; for exp the Taylor series, cut where the next term is
below 2^-56 of the result), evaluated by Estrin's scheme (short dependency chains: a vectorised
loop body is latency-bound). Measured against libm (``test_vmath.py``): within a few ulp on
the whole double range for atan/exp/log, and for sin/cos/tan while |x| < 2^26 pi/2 (Cody-Waite
reduction; beyond that the result loses digits but stays in [-1, 1]). NaN and +-inf give what
libm gives. The polynomials use fused multiply-adds (:func:`fma`, IEEE, so the same result on
every machine): fewer roundings, and sin, atan, exp, log 25-37 % faster in a vectorised loop.
"""

from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from .jit import vkernel

# pi/2 = PIO2_1 + PIO2_2 + PIO2_3; the first two have 26 significant bits, so n * PIO2_k is
# exact for |n| < 2^26 (Cody-Waite reduction).
PIO2_1 = 1.5707963109016418
PIO2_2 = 1.5893254712295857e-08
PIO2_3 = 6.123233995736766e-17
TWO_OVER_PI = 0.6366197723675814
PI_2 = 1.5707963267948966
PI_4 = 0.7853981633974483
TAN_3PI_8 = 2.414213562373095  # 1 + sqrt 2
TAN_PI_8 = 0.41421356237309503  # sqrt 2 - 1
LN2_HI = 0.6931471803691238  # 32 significant bits: n * LN2_HI exact for |n| < 2^21
LN2_LO = 1.9082149292705877e-10
LOG2E = 1.4426950408889634
SQRT2 = 1.4142135623730951
ROUND = 6755399441055744.0  # 1.5 * 2^52: (x + ROUND) - ROUND rounds x to an integer
EXP_MAX = 709.782712893384  # log(DBL_MAX)
EXP_MIN = -745.1332191019412  # log of the smallest subnormal


@intrinsic
def _bits(typingctx, x):
    """The IEEE-754 bit pattern of a float64 as int64."""

    def codegen(context, builder, sig, args):
        return builder.bitcast(args[0], ir.IntType(64))

    return types.int64(types.float64), codegen


@intrinsic
def _float(typingctx, n):
    """The float64 whose bit pattern is the int64 n."""

    def codegen(context, builder, sig, args):
        return builder.bitcast(args[0], ir.DoubleType())

    return types.float64(types.int64), codegen


@intrinsic
def fma(typingctx, a, b, c):
    """a b + c rounded once (IEEE fused multiply-add, ``llvm.fma``): the same result on every
    machine; a vector FMA instruction on x86-64 with FMA (Haswell and later)."""

    def codegen(context, builder, sig, args):
        d = ir.DoubleType()
        fn = builder.module.declare_intrinsic("llvm.fma", [d], ir.FunctionType(d, [d, d, d]))
        return builder.call(fn, args)

    return types.float64(types.float64, types.float64, types.float64), codegen


@vkernel
def _pow2i(n: int) -> float:
    """2^n for an integer -1022 <= n <= 1023 (built from its exponent bits)."""
    return _float((n + 1023) << 52)


@vkernel
def _unit(x: float) -> float:
    """x saturated to [-1, 1]; NaN passes through."""
    return -1.0 if x < -1.0 else (1.0 if x > 1.0 else x)


# Minimax coefficients of fdlibm (Sun Microsystems 1993: k_sin.c, k_cos.c, s_atan.c, e_log.c):
# 6, 6, 11 and 7 terms where the Taylor series needs 8, 8, 20 and 11 for the same accuracy
# (polynomial error in exact arithmetic, checked in long double: below 0.04 ulp on the
# reduced intervals of sin, cos, atan and log).
S1, S2, S3 = -1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04
S4, S5, S6 = 2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10
C1, C2, C3 = 4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05
C4, C5, C6 = -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11
AT = (3.33333333333329318027e-01, -1.99999999998764832476e-01, 1.42857142725034663711e-01,
      -1.11111104054623557880e-01, 9.09088713343650656196e-02, -7.69187620504482999495e-02,
      6.66107313738753120669e-02, -5.83357013379057348645e-02, 4.97687799461593236017e-02,
      -3.65315727442169155270e-02, 1.62858201153657823623e-02)  # fmt: skip
AT0, AT1, AT2, AT3, AT4, AT5, AT6, AT7, AT8, AT9, AT10 = AT
LG1, LG2, LG3 = 6.666666666666735130e-01, 3.999999999940941908e-01, 2.857142874366239149e-01
LG4, LG5, LG6 = 2.222219843214978396e-01, 1.818357216161805012e-01, 1.531383769920937332e-01
LG7 = 1.479819860511658591e-01


@vkernel
def _sin_poly(r: float, z: float) -> float:
    """sin r on |r| <= pi/4, z = r^2: r + r z (S1 + S2 z + ... + S6 z^5)."""
    z2 = z * z
    z4 = z2 * z2
    p = fma(z4, fma(z, S6, S5), fma(z2, fma(z, S4, S3), fma(z, S2, S1)))
    return fma(r * z, p, r)


@vkernel
def _cos_poly(z: float) -> float:
    """cos r on |r| <= pi/4, z = r^2: 1 - z/2 + z^2 (C1 + C2 z + ... + C6 z^5)."""
    z2 = z * z
    z4 = z2 * z2
    p = fma(z4, fma(z, C6, C5), fma(z2, fma(z, C4, C3), fma(z, C2, C1)))
    return fma(z2, p, 1.0 - 0.5 * z)


@vkernel
def sincos(x: float) -> tuple[float, float]:
    """(sin x, cos x): x = n pi/2 + r with |r| <= pi/4, then the quadrant n mod 4."""
    shifted = x * TWO_OVER_PI + ROUND
    n = shifted - ROUND
    q = _bits(shifted) & 3  # n mod 4 (the low bits of the rounded sum)
    r = ((x - n * PIO2_1) - n * PIO2_2) - n * PIO2_3
    z = r * r
    s = _sin_poly(r, z)
    c = _cos_poly(z)
    sin_x = c if q & 1 else s
    cos_x = s if q & 1 else c
    if q & 2:
        sin_x = -sin_x
    if (q + 1) & 2:
        cos_x = -cos_x
    # beyond |n| = 2^26 the reduction loses digits: keep the results in [-1, 1] (NaN stays)
    return _unit(sin_x), _unit(cos_x)


@vkernel
def sin(x: float) -> float:
    """sin x (see :func:`sincos`)."""
    return sincos(x)[0]


@vkernel
def cos(x: float) -> float:
    """cos x (see :func:`sincos`)."""
    return sincos(x)[1]


@vkernel
def tan(x: float) -> float:
    """tan x = sin x / cos x (see :func:`sincos`)."""
    s, c = sincos(x)
    return s / c


@vkernel
def _atan_series(z: float) -> float:
    """(t - atan t)/t^3 ~ AT0 + AT1 z + ... + AT10 z^10, z = t^2 <= tan(pi/8)^2 (fdlibm's
    minimax polynomial; Estrin's scheme: a dependency chain of 5 multiply-adds)."""
    z2 = z * z
    z4 = z2 * z2
    z8 = z4 * z4
    q0 = fma(z2, fma(z, AT3, AT2), fma(z, AT1, AT0))
    q1 = fma(z2, fma(z, AT7, AT6), fma(z, AT5, AT4))
    q2 = fma(z2, AT10, fma(z, AT9, AT8))
    return fma(z8, q2, fma(z4, q1, q0))


@vkernel
def atan(x: float) -> float:
    """atan x: |x| reduced to |t| <= tan(pi/8) by atan a = pi/4 + atan((a-1)/(a+1)) or
    pi/2 + atan(-1/a), then the polynomial of :func:`_atan_series`."""
    a = abs(x)
    big = a > TAN_3PI_8
    mid = a > TAN_PI_8
    num = -1.0 if big else (a - 1.0 if mid else a)
    den = a if big else (a + 1.0 if mid else 1.0)
    offset = PI_2 if big else (PI_4 if mid else 0.0)
    t = num / den
    z = t * t
    p = _atan_series(z)
    r = offset + fma(-(t * z), p, t)
    return -r if x < 0.0 else r  # NaN: r is NaN


@vkernel
def exp(x: float) -> float:
    """exp x = 2^n exp r, |r| <= ln2/2, Taylor to r^13; 2^n applied in two halves so that
    subnormal results come out right."""
    xc = EXP_MIN if x < EXP_MIN else (EXP_MAX if x > EXP_MAX else x)  # n in range; NaN stays
    shifted = xc * LOG2E + ROUND
    n = shifted - ROUND
    r = (xc - n * LN2_HI) - n * LN2_LO
    r2 = r * r
    r4 = r2 * r2
    r8 = r4 * r4
    p0 = fma(r2, fma(r, 1.0 / 120.0, 1.0 / 24.0), fma(r, 1.0 / 6.0, 0.5))
    p1 = fma(r2, fma(r, 1.0 / 362880.0, 1.0 / 40320.0), fma(r, 1.0 / 5040.0, 1.0 / 720.0))
    p2 = fma(r2, fma(r, 1.0 / 6227020800.0, 1.0 / 479001600.0),
             fma(r, 1.0 / 39916800.0, 1.0 / 3628800.0))  # fmt: skip
    p = fma(r8, p2, fma(r4, p1, p0))
    e_r = 1.0 + fma(r2, p, r)
    k = (_bits(shifted) << 32) >> 32  # n as a signed integer from the low bits
    half = k >> 1
    y = e_r * _pow2i(half) * _pow2i(k - half)
    if x > EXP_MAX:
        return math.inf
    if x < EXP_MIN:
        return 0.0
    return y  # NaN: xc, and so y, is NaN


@vkernel
def log(x: float) -> float:
    """log x = e ln2 + log m, m in [sqrt(1/2), sqrt 2): log m = 2 atanh s = 2s + s z R(z),
    s = (m-1)/(m+1), z = s^2, R fdlibm's minimax polynomial (LG1..LG7, e_log.c); subnormals
    are scaled by 2^54 first."""
    sub = x < 2.2250738585072014e-308
    xs = x * 18014398509481984.0 if sub else x
    b = _bits(xs)
    e = ((b >> 52) & 0x7FF) - (1077 if sub else 1023)
    m = _float((b & 0xFFFFFFFFFFFFF) | 0x3FF0000000000000)  # mantissa in [1, 2)
    if m > SQRT2:
        m = 0.5 * m
        e += 1
    s = (m - 1.0) / (m + 1.0)
    z = s * s
    z2 = z * z
    z4 = z2 * z2
    p = fma(z4, fma(z2, LG7, fma(z, LG6, LG5)), fma(z2, fma(z, LG4, LG3), fma(z, LG2, LG1)))
    f = float(e)
    y = f * LN2_HI + (2.0 * s + fma(s * z, p, f * LN2_LO))
    if x == 0.0:
        return -math.inf
    if x < 0.0:
        return math.nan
    if not x < math.inf:
        return x  # +inf, NaN
    return y


@vkernel
def pow(x: float, y: float) -> float:
    """x^y = exp(y log|x|), with libm's special cases (y = 0, x = 1, negative x with an
    integer y, NaN)."""
    r = exp(y * log(abs(x)))
    if x < 0.0:
        y_int = y == np.floor(y)
        odd = y_int and 2.0 * np.floor(0.5 * y) != y
        r = (-r if odd else r) if y_int else math.nan
    if y == 0.0 or x == 1.0:
        return 1.0
    return r
