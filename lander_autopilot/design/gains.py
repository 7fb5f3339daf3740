"""Gain design: pole placement and LQR (control reference eq 5, 18-21), via python-control.

Convention (eq 5, 18): ``u - u_e = -K (x - x_e)``, so the closed loop is ``x' = (A - B K) x``.
(The reference writes ``u = -K dx`` with ``dx = x_e - x``; read literally that flips the sign
of the feedback. Its own baseline, ``t = t_e + k_p (z_e - z)``, is ``u = u_e + K (x_e - x)``:
the form used here.)

``control.place`` (Tits-Yang, scipy) refuses a pole repeated more than ``rank(B)`` times and a
``B`` with dependent columns; ``control.place_varga`` (SLICOT SB01BD via slycot) handles both and
also leaves uncontrollable modes where they are. :func:`place_poles` picks the method and says
which it used. SB01BD is not reliable with a rank-deficient ``B`` (four throttles, three torques):
for some pole sets (e.g. a complex pair with a repeated real pole) it returns gains of 1e45 and
poles of 1e30 with only a warning. Every placement is therefore checked against the request, and
a miss is redone by ``control.place`` on the column space of ``B`` (``B = B_r V^T`` with ``V`` an
orthonormal basis of ``B``'s row space, ``K = V K_r``: the minimum-norm throttle allocation). ``import control`` costs ~1.5 s, so it happens inside the functions.
"""
from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import numpy as np

from . import DesignError
from .controllability import check_shapes, controllability


@dataclass(frozen=True)
class GainDesign:
    """A state-feedback gain and what it achieves.

    Attributes
    ----------
    K : ndarray (m, n)
        Gain; ``K[i, j]``: input (thruster) ``i`` responds to state ``j``.
    method : str
        ``"place"``, ``"place_varga"``, ``"place on the column space of B"`` or ``"lqr"``.
    requested : ndarray | None
        Requested closed-loop poles (pole placement only).
    poles : ndarray
        Eigenvalues of ``A - B K``, sorted by real part then imaginary part.
    """

    K: np.ndarray
    method: str
    requested: np.ndarray | None
    poles: np.ndarray


def _sorted(p: np.ndarray) -> np.ndarray:
    p = np.asarray(p, dtype=complex)
    return p[np.lexsort((p.imag, p.real))]


def closed_loop_poles(A: np.ndarray, B: np.ndarray, K: np.ndarray) -> np.ndarray:
    """Eigenvalues of ``A - B K`` (eq 5, 19), sorted."""
    return _sorted(np.linalg.eigvals(np.asarray(A) - np.asarray(B) @ np.asarray(K)))




def place_poles(A: np.ndarray, B: np.ndarray, poles: np.ndarray | list[complex]) -> GainDesign:
    """``K`` with ``eig(A - B K) = poles`` (eq 5).

    Uses ``control.place`` when it applies (``B`` of full column rank and no pole repeated
    more than ``rank(B)`` times), else ``control.place_varga``. For an uncontrollable pair
    Varga's method moves only the controllable modes; :class:`GainDesign.poles` shows where
    the others stayed.
    """
    import control

    A, B = check_shapes(A, B)
    p = np.asarray(poles, dtype=complex).reshape(-1)
    if p.size != A.shape[0]:
        raise DesignError(f"poles: need {A.shape[0]} poles for a {A.shape[0]}-state model, got {p.size}")
    if not np.all(np.isfinite(p)):
        raise DesignError(f"poles must be finite, got {p.tolist()}")
    # Complex poles must come in conjugate pairs for a real K.
    if not np.allclose(_sorted(p), _sorted(p.conj())):
        raise DesignError(f"complex poles must come in conjugate pairs, got {p.tolist()}")
    rank_b = int(np.linalg.matrix_rank(B))
    multiplicity = max(Counter(np.round(p, 12).tolist()).values())
    full_column_rank = rank_b == B.shape[1]
    ctrb = controllability(A, B)
    if full_column_rank and multiplicity <= rank_b and ctrb.controllable:
        K = np.asarray(control.place(A, B, p))
        method = "place"
    else:
        K = np.real_if_close(np.asarray(control.place_varga(A, B, p))).astype(float)
        method = "place_varga"
        if ctrb.controllable and multiplicity <= rank_b and not _placed(p, A, B, K):
            K = _column_space_gain(A, B, p, rank_b)
            method = "place on the column space of B"
    K = np.real_if_close(K).astype(float)
    return GainDesign(K=K, method=method, requested=_sorted(p), poles=closed_loop_poles(A, B, K))


def place_on_column_space(A: np.ndarray, B: np.ndarray, poles: np.ndarray | list[complex]) -> GainDesign:
    """``K`` with ``eig(A - B K) = poles`` by ``control.place`` on the column space of ``B``.

    ``B = B_r V^T`` with ``V`` an orthonormal basis of ``B``'s row space; ``K = V K_r`` is the
    minimum-norm throttle allocation of the gain ``K_r`` placed for ``(A, B V)``. This is what
    :func:`place_poles` falls back on when SB01BD misses; whether SB01BD misses a given pole set
    depends on the machine's floating point, so the fallback is also callable (and tested) alone.
    Needs a controllable pair and no pole repeated more than ``rank(B)`` times.
    """
    A, B = check_shapes(A, B)
    p = np.asarray(poles, dtype=complex).reshape(-1)
    K = np.real_if_close(_column_space_gain(A, B, p, int(np.linalg.matrix_rank(B)))).astype(float)
    return GainDesign(K=K, method="place on the column space of B", requested=_sorted(p),
                      poles=closed_loop_poles(A, B, K))


def _column_space_gain(A: np.ndarray, B: np.ndarray, p: np.ndarray, rank_b: int) -> np.ndarray:
    import control

    V = np.linalg.svd(B)[2][:rank_b].T  # orthonormal basis of B's row space (m x r)
    return V @ np.asarray(control.place(A, B @ V, p))


# A placement that misses a requested pole by more than this (relative to the largest pole) has
# failed numerically; a good one is off by ~1e-8 even for repeated poles (eps^(1/2)).
PLACEMENT_TOLERANCE = 1e-6


def _placed(p: np.ndarray, A: np.ndarray, B: np.ndarray, K: np.ndarray) -> bool:
    """True when ``eig(A - B K)`` matches the requested poles ``p``."""
    achieved = closed_loop_poles(A, B, K) if np.all(np.isfinite(K)) else None
    if achieved is None or not np.all(np.isfinite(achieved)):
        return False
    return match_poles(_sorted(p), achieved) <= PLACEMENT_TOLERANCE * max(1.0, float(np.abs(p).max()))


def lqr(A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray) -> GainDesign:
    """LQR gain minimising ``int (x^T Q x + u^T R u) dt`` (``control.lqr``).

    ``Q`` (n x n) symmetric positive semi-definite, ``R`` (m x m) positive definite. Fails
    with :class:`DesignError` if ``(A, B)`` is not stabilisable (e.g. vertical thrusters:
    rotation about body z cannot be controlled).
    """
    import control

    A, B = check_shapes(A, B)
    n, m = B.shape
    Q = np.atleast_2d(np.asarray(Q, dtype=float))
    R = np.atleast_2d(np.asarray(R, dtype=float))
    if Q.shape != (n, n):
        raise DesignError(f"Q must have shape ({n}, {n}), got {Q.shape}")
    if R.shape != (m, m):
        raise DesignError(f"R must have shape ({m}, {m}), got {R.shape}")
    try:
        K, _, _ = control.lqr(A, B, Q, R)
    except Exception as exc:  # python-control raises several types for a singular Riccati equation
        raise DesignError(f"LQR failed (is (A, B) stabilisable?): {' '.join(str(exc).split())}") from None
    K = np.asarray(K, dtype=float)
    return GainDesign(K=K, method="lqr", requested=None, poles=closed_loop_poles(A, B, K))


def match_poles(requested: np.ndarray, achieved: np.ndarray) -> float:
    """Largest distance between requested and achieved poles after optimal pairing."""
    from scipy.optimize import linear_sum_assignment

    r = np.asarray(requested, dtype=complex)
    a = np.asarray(achieved, dtype=complex)
    cost = np.abs(r[:, None] - a[None, :])
    i, j = linear_sum_assignment(cost)
    return float(cost[i, j].max())
