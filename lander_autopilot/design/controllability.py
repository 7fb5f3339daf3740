"""Controllability (control reference eq 6): ``P = [B, AB, ..., A^(n-1) B]``, rank, uncontrollable subspace.

Reachable states lie in the column space of ``P``; the states no input can reach span its left
null space (solutions of ``P^T x = 0``, section 3.4), found here from the SVD ``P = U S V^T``:
the columns of ``U`` beyond the rank.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import DesignError


@dataclass(frozen=True)
class Controllability:
    """Result of :func:`controllability`.

    Attributes
    ----------
    P : ndarray (n, n m)
        Controllability matrix (eq 6).
    rank : int
        Numerical rank of ``P``.
    uncontrollable : ndarray (n, n - rank)
        Orthonormal basis of the left null space of ``P``; columns are state directions.
    singular_values : ndarray
        Singular values of ``P`` (descending).
    tol : float
        Singular values at or below ``tol`` count as zero.
    """

    P: np.ndarray
    rank: int
    uncontrollable: np.ndarray
    singular_values: np.ndarray
    tol: float

    @property
    def controllable(self) -> bool:
        return self.rank == self.P.shape[0]

def check_shapes(A: np.ndarray, B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``A`` (n x n) and ``B`` (n x m, a vector taken as one column) as float arrays; errors name the matrix."""
    A = np.atleast_2d(np.asarray(A, dtype=float))
    B = np.asarray(B, dtype=float)
    if B.ndim == 1:
        B = B[:, None]
    n = A.shape[0]
    if A.shape != (n, n):
        raise DesignError(f"A must be square, got shape {A.shape}")
    if B.shape[0] != n:
        raise DesignError(f"B must have {n} rows to match A, got shape {B.shape}")
    return A, B


def controllability_matrix(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``P = [B, AB, A^2 B, ..., A^(n-1) B]`` (eq 6)."""
    A, B = check_shapes(A, B)
    blocks = [B]
    for _ in range(A.shape[0] - 1):
        blocks.append(A @ blocks[-1])
    return np.hstack(blocks)


def controllability(A: np.ndarray, B: np.ndarray, rtol: float | None = None) -> Controllability:
    """Rank of eq 6's ``P`` and an orthonormal basis of the states it cannot reach.

    Tolerance: singular values below ``rtol * s_max`` are zero; by default
    ``rtol = max(P.shape) * eps`` (numpy's ``matrix_rank`` rule), the size of rounding
    errors in an SVD of ``P``.
    """
    P = controllability_matrix(A, B)
    U, s, _ = np.linalg.svd(P)
    if rtol is None:
        rtol = max(P.shape) * np.finfo(float).eps
    tol = float(rtol * (s[0] if s.size else 0.0))
    rank = int(np.sum(s > tol))
    return Controllability(P=P, rank=rank, uncontrollable=U[:, rank:], singular_values=s, tol=tol)
