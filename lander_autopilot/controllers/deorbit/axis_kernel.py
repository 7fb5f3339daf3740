"""The thrust axis's attitude (:func:`.geometry.thrust_axis_attitude`) as one compiled call.

The de-orbit laws point body +z along a direction every control period (retrograde through the
entry, along the airflow under the chute): ~20,000 calls a flight, each a dozen numpy calls on
3-vectors and 3 x 3 matrices whose dispatch costs far more than their arithmetic. This is the same
arithmetic on scalars, numba-compiled, in the same operation order as the numpy formula
(:func:`.geometry.thrust_axis_attitude_numpy`):

* ``R(q)`` by eq 13 (:func:`lander_sim.physics.rotation.quat_to_matrix`), the cross product
  ``a x b = (a1 b2 - a2 b1, a2 b0 - a0 b2, a0 b1 - a1 b0)`` as ``np.cross`` computes it;
* every dot product (the norms ``sqrt(x . x)``, ``z . d`` and the entries of the 3 x 3 products
  ``K K`` and ``R M^T``) as a chain of fused multiply-adds in index order,
  ``fma(x2, y2, fma(x1, y1, x0 y0))``: what OpenBLAS's ``ddot`` and small ``dgemm`` kernels compute
  on a CPU with FMA (x86-64 with AVX2 or AVX-512), so on such a CPU the attitude is numpy's to the
  bit; on one whose BLAS does not fuse, the two differ by rounding only (each dot product's error
  is a few units in the last place either way);
* Rodrigues' ``M = I + sin(a) K + (1 - cos(a)) K^2`` and Shepperd's ``matrix -> quaternion``
  (:func:`lander_sim.physics.rotation.matrix_to_quat`) term by term.

Without numba the numpy formula runs instead (``HAVE_NUMBA`` False).
"""
from __future__ import annotations

import math
from typing import Any

try:
    from llvmlite import ir
    from numba import njit, types
    from numba.extending import intrinsic

    HAVE_NUMBA = True
except ImportError:  # pragma: no cover - exercised only where numba is absent
    HAVE_NUMBA = False

    def njit(*args: Any, **kwargs: Any) -> Any:  # type: ignore[no-redef]  # the stand-in for numba's, same name on purpose
        if args and callable(args[0]):
            return args[0]
        return lambda f: f

__all__ = ["HAVE_NUMBA", "fused_dot3", "load", "thrust_axis_quaternion"]


def _fma_typing(typingctx: Any, a: Any, b: Any, c: Any) -> Any:
    """``a b + c`` rounded once (LLVM's ``llvm.fma.f64``: exact on every target, in hardware where
    the CPU has FMA); numba's intrinsic protocol: the signature and its code generator."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        d = ir.DoubleType()
        fn = builder.module.declare_intrinsic("llvm.fma", [d], ir.FunctionType(d, [d, d, d]))
        return builder.call(fn, args)

    return sig, codegen


def _fma_unfused(a: float, b: float, c: float) -> float:  # pragma: no cover - only without numba
    return a * b + c


#: ``fma(a, b, c)``, compiled; without numba (where the numpy formula runs instead) rounded twice
_fma: Any = intrinsic(_fma_typing) if HAVE_NUMBA else _fma_unfused


@njit(cache=True)
def _dot3(a0: float, a1: float, a2: float, b0: float, b1: float, b2: float) -> float:
    return _fma(a2, b2, _fma(a1, b1, a0 * b0))


@njit(cache=True)
def fused_dot3(a0: float, a1: float, a2: float, b0: float, b1: float, b2: float) -> float:
    """``a . b`` as fused multiply-adds in index order (the module docstring)."""
    return _dot3(a0, a1, a2, b0, b1, b2)


@njit(cache=True)
def thrust_axis_quaternion(s: float, a: float, b: float, c: float,
                           x: float, y: float, z: float, parallel_sine: float) -> tuple[float, float, float, float]:
    """The attitude (world -> body quaternion ``(s, a, b, c)`` in, the new one out) nearest ``q``
    with body +z along the world direction ``(x, y, z)``; ``parallel_sine``: :data:`.geometry.PARALLEL_SINE`."""
    # R(q), eq 13: rows are the body axes in world coordinates
    r00 = s * s + a * a - b * b - c * c
    r01 = 2.0 * (a * b + s * c)
    r02 = 2.0 * (a * c - s * b)
    r10 = 2.0 * (a * b - s * c)
    r11 = s * s - a * a + b * b - c * c
    r12 = 2.0 * (s * a + b * c)
    r20 = 2.0 * (s * b + a * c)
    r21 = 2.0 * (b * c - s * a)
    r22 = s * s - a * a - b * b + c * c
    nd = math.sqrt(_dot3(x, y, z, x, y, z))
    d0, d1, d2 = x / nd, y / nd, z / nd
    # axis = z_body x d
    k0 = r21 * d2 - r22 * d1
    k1 = r22 * d0 - r20 * d2
    k2 = r20 * d1 - r21 * d0
    sn = math.sqrt(_dot3(k0, k1, k2, k0, k1, k2))
    cth = _dot3(r20, r21, r22, d0, d1, d2)
    if sn < parallel_sine:
        if cth > 0:
            return s, a, b, c
        # opposite: any perpendicular axis does; take body x
        k0, k1, k2, sn, cth = r00, r01, r02, 1.0, -1.0
    nk = math.sqrt(_dot3(k0, k1, k2, k0, k1, k2))
    k0, k1, k2 = k0 / nk, k1 / nk, k2 / nk
    # K = [k]x, and K K entry by entry (a fused chain over the inner index, zeros included)
    K00, K01, K02 = 0.0, -k2, k1
    K10, K11, K12 = k2, 0.0, -k0
    K20, K21, K22 = -k1, k0, 0.0
    Q00 = _dot3(K00, K01, K02, K00, K10, K20)
    Q01 = _dot3(K00, K01, K02, K01, K11, K21)
    Q02 = _dot3(K00, K01, K02, K02, K12, K22)
    Q10 = _dot3(K10, K11, K12, K00, K10, K20)
    Q11 = _dot3(K10, K11, K12, K01, K11, K21)
    Q12 = _dot3(K10, K11, K12, K02, K12, K22)
    Q20 = _dot3(K20, K21, K22, K00, K10, K20)
    Q21 = _dot3(K20, K21, K22, K01, K11, K21)
    Q22 = _dot3(K20, K21, K22, K02, K12, K22)
    ang = math.atan2(sn, cth)
    si = math.sin(ang)
    co = 1 - math.cos(ang)
    # M = I + sin K + (1 - cos) K^2 (Rodrigues), summed as numpy sums the three arrays
    m00 = (1.0 + si * K00) + co * Q00
    m01 = (0.0 + si * K01) + co * Q01
    m02 = (0.0 + si * K02) + co * Q02
    m10 = (0.0 + si * K10) + co * Q10
    m11 = (1.0 + si * K11) + co * Q11
    m12 = (0.0 + si * K12) + co * Q12
    m20 = (0.0 + si * K20) + co * Q20
    m21 = (0.0 + si * K21) + co * Q21
    m22 = (1.0 + si * K22) + co * Q22
    # P = R M^T
    p00 = _dot3(r00, r01, r02, m00, m01, m02)
    p01 = _dot3(r00, r01, r02, m10, m11, m12)
    p02 = _dot3(r00, r01, r02, m20, m21, m22)
    p10 = _dot3(r10, r11, r12, m00, m01, m02)
    p11 = _dot3(r10, r11, r12, m10, m11, m12)
    p12 = _dot3(r10, r11, r12, m20, m21, m22)
    p20 = _dot3(r20, r21, r22, m00, m01, m02)
    p21 = _dot3(r20, r21, r22, m10, m11, m12)
    p22 = _dot3(r20, r21, r22, m20, m21, m22)
    # matrix -> quaternion (Shepperd), the largest of the four squared components first
    tr = p00 + p11 + p22
    k = 0
    best = tr
    if p00 > best:
        k, best = 1, p00
    if p11 > best:
        k, best = 2, p11
    if p22 > best:
        k = 3
    if k == 0:
        w = 0.5 * math.sqrt(max(1.0 + tr, 0.0))
        f = 0.25 / w
        q0, q1, q2, q3 = w, (p12 - p21) * f, (p20 - p02) * f, (p01 - p10) * f
    elif k == 1:
        w = 0.5 * math.sqrt(max(1.0 + 2.0 * p00 - tr, 0.0))
        f = 0.25 / w
        q0, q1, q2, q3 = (p12 - p21) * f, w, (p01 + p10) * f, (p02 + p20) * f
    elif k == 2:
        w = 0.5 * math.sqrt(max(1.0 + 2.0 * p11 - tr, 0.0))
        f = 0.25 / w
        q0, q1, q2, q3 = (p20 - p02) * f, (p01 + p10) * f, w, (p12 + p21) * f
    else:
        w = 0.5 * math.sqrt(max(1.0 + 2.0 * p22 - tr, 0.0))
        f = 0.25 / w
        q0, q1, q2, q3 = (p01 - p10) * f, (p02 + p20) * f, (p12 + p21) * f, w
    if q0 < 0.0:
        q0, q1, q2, q3 = -q0, -q1, -q2, -q3
    nq = math.sqrt(_fma(q3, q3, _fma(q2, q2, _fma(q1, q1, q0 * q0))))
    return q0 / nq, q1 / nq, q2 / nq, q3 / nq


def load() -> None:
    """Compile (or load from numba's cache) the kernel now, with the law: its first call costs
    ~0.3 s even from the cache, more than a control period, so it is not left to the flight's first
    period."""
    if HAVE_NUMBA:
        thrust_axis_quaternion(1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1e-12)
