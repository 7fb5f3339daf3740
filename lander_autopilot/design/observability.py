"""Observability, steady-state Kalman gains and LQG for the lander's hover models.

The control reference stops at full state feedback (section 3.4: "as we are considering full
state-feedback, [observability] will not be explored further"). With only the outputs
``y = C x + D u`` of the sensors the state must be reconstructed, which is possible exactly when
the **observability matrix** (the dual of eq 6)::

    O = [C; C A; C A^2; ...; C A^(n-1)]

has full rank ``n``. The states no output can ever see span its null space (``O x = 0``): a
change along them leaves every output and all its derivatives unchanged (Kailath, *Linear
Systems*, 1980, section 2.3; Franklin, Powell and Emami-Naeini, *Feedback Control of Dynamic
Systems*, 7th ed., section 7.7). It is found here from the SVD ``O = U S V^T``: the rows of
``V^T`` beyond the rank.

**Sensor output matrices** (:func:`sensor_outputs`), for the models of :mod:`.altitude` (eq 16),
:mod:`.attitude` (eq 28, or its quaternion form at rest) and :mod:`.translational` (12 states,
local ENU frame about the hover):

==================  =============================================  ===============================
sensor              measures                                       rows of ``C`` (``D``)
==================  =============================================  ===============================
``altimeter``       altitude (vertical beam at the hover)          ``p_U`` (``z``)
``doppler``         velocity over the ground                       ``v_E v_N v_U`` (``z'``)
``star_tracker``    attitude                                       the three attitude states
``gyro``            body rates                                     ``wx wy wz``
``accelerometer``   specific force ``f_B = R_BW (a_W - g_W)``      zero rows; ``D = F_B / m``
==================  =============================================  ===============================

The accelerometer measures the thrust (and drag) per unit mass in the body frame: gravity acts on
the proof mass as on the vehicle, so in vacuum ``f_B = F_B t / m`` exactly, a function of the
input alone. Its rows of ``C`` are zero and it adds nothing to the rank: a navigation filter uses
it as the input of its propagation (:mod:`lander_autopilot.estimation`), not as a measurement.

**Steady-state Kalman gain** (:func:`kalman`): for ``x' = A x + B u + G w``, ``y = C x + v`` with
white ``w``, ``v`` of spectral densities ``Q_N``, ``R_N``, ``L = P C^T R_N^-1`` where ``P`` solves
the filter Riccati equation ``A P + P A^T - P C^T R_N^-1 C P + G Q_N G^T = 0``
(python-control ``lqe``; ``dlqe`` for the sampled filter). A sensor sampled every ``dt`` with
standard deviation ``sigma`` has the density ``R_N = sigma^2 dt`` (Gelb, *Applied Optimal
Estimation*, 1974, section 4.3).

**LQG and the separation principle** (:func:`lqg`): the regulator ``u = -K x_hat`` on the
estimator ``x_hat' = A x_hat + B u + L (y - C x_hat)``. In the coordinates ``(x, e = x - x_hat)``
the closed loop is block triangular::

    [x']   [A - B K     B K  ] [x]
    [e'] = [   0     A - L C ] [e]

so its eigenvalues are those of ``A - B K`` (the regulator) and of ``A - L C`` (the estimator),
whatever ``K`` and ``L`` are: the two can be designed apart.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from . import DesignError
from .gains import closed_loop_poles, lqr

#: Sensors whose output matrices :func:`sensor_outputs` builds.
SENSORS = ("altimeter", "doppler", "star_tracker", "gyro", "accelerometer")


@dataclass(frozen=True)
class Observability:
    """Result of :func:`observability`.

    Attributes
    ----------
    O : ndarray (p n, n)
        Observability matrix.
    rank : int
        Its numerical rank.
    unobservable : ndarray (n, n - rank)
        Orthonormal basis of its null space; columns are state directions no output sees.
    singular_values : ndarray
        Singular values of ``O`` (descending).
    tol : float
        Singular values at or below ``tol`` count as zero.
    """

    O: np.ndarray
    rank: int
    unobservable: np.ndarray
    singular_values: np.ndarray
    tol: float

    @property
    def observable(self) -> bool:
        return self.rank == self.O.shape[1]


def _check(A: np.ndarray, C: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    A = np.atleast_2d(np.asarray(A, dtype=float))
    C = np.atleast_2d(np.asarray(C, dtype=float))
    n = A.shape[0]
    if A.shape != (n, n):
        raise DesignError(f"A must be square, got shape {A.shape}")
    if C.shape[1] != n:
        raise DesignError(f"C must have {n} columns to match A, got shape {C.shape}")
    return A, C


def observability_matrix(A: np.ndarray, C: np.ndarray) -> np.ndarray:
    """``O = [C; C A; ...; C A^(n-1)]``."""
    A, C = _check(A, C)
    blocks = [C]
    for _ in range(A.shape[0] - 1):
        blocks.append(blocks[-1] @ A)
    return np.vstack(blocks)


def observability(A: np.ndarray, C: np.ndarray, rtol: float | None = None) -> Observability:
    """Rank of ``O`` and an orthonormal basis of the states no output sees.

    Tolerance as :func:`.controllability.controllability`: singular values below
    ``rtol * s_max`` are zero, by default ``rtol = max(O.shape) * eps``. A ``C`` of zero rows only
    (no sensor) has rank 0 and every state unobservable.
    """
    O = observability_matrix(A, C)
    n = O.shape[1]
    if not np.any(O):
        return Observability(O=O, rank=0, unobservable=np.eye(n), singular_values=np.zeros(min(O.shape)), tol=0.0)
    _, s, Vt = np.linalg.svd(O)
    if rtol is None:
        rtol = max(O.shape) * np.finfo(float).eps
    tol = float(rtol * s[0])
    rank = int(np.sum(s > tol))
    return Observability(O=O, rank=rank, unobservable=Vt[rank:].T, singular_values=s, tol=tol)


@dataclass(frozen=True)
class SensorOutputs:
    """``y = C x + D u`` of a sensor set on one linear model; ``labels`` name the rows of ``C``."""

    C: np.ndarray
    D: np.ndarray
    labels: tuple[str, ...]


#: The state names each model's sensor rows are picked from.
_ROWS: dict[str, dict[str, tuple[str, ...]]] = {
    "altitude": {"altimeter": ("z",), "doppler": ("z_dot",)},
    "attitude": {"star_tracker": ("phi", "theta", "psi"), "gyro": ("wx", "wy", "wz")},
    "translational": {
        "altimeter": ("p_U",), "doppler": ("v_E", "v_N", "v_U"),
        "star_tracker": ("phi", "theta", "psi"), "gyro": ("wx", "wy", "wz"),
    },
}


def sensor_outputs(model: str, states: Sequence[str], sensors: Sequence[str], n_inputs: int,
                   specific_force_D: np.ndarray | None = None) -> SensorOutputs:
    """``C`` (and ``D``) of ``sensors`` on the linear model ``model`` (``"altitude"``, ``"attitude"``,
    ``"translational"``) whose states are named ``states``.

    A sensor that sees none of the model's states (the gyro on the altitude model) adds no row.
    The accelerometer adds three rows of zeros in ``C`` with ``D = specific_force_D`` (the
    specific force per unit throttle, body frame; module docstring), required when it is listed.
    """
    if model not in _ROWS:
        raise DesignError(f"unknown model {model!r}; choose one of {', '.join(_ROWS)}")
    n = len(states)
    rows_C: list[np.ndarray] = []
    rows_D: list[np.ndarray] = []
    labels: list[str] = []
    for s in sensors:
        if s not in SENSORS:
            raise DesignError(f"unknown sensor {s!r}; choose from {', '.join(SENSORS)}")
        if s == "accelerometer":
            if specific_force_D is None:
                raise DesignError("the accelerometer needs specific_force_D (3 x inputs): its output is the input's")
            D = np.asarray(specific_force_D, dtype=float)
            if D.shape != (3, n_inputs):
                raise DesignError(f"specific_force_D must have shape (3, {n_inputs}), got {D.shape}")
            for k in range(3):
                rows_C.append(np.zeros(n))
                rows_D.append(D[k])
                labels.append(f"f_B{'xyz'[k]}")
            continue
        for name in _ROWS[model].get(s, ()):
            row = np.zeros(n)
            row[list(states).index(name)] = 1.0
            rows_C.append(row)
            rows_D.append(np.zeros(n_inputs))
            labels.append(name)
    C = np.array(rows_C) if rows_C else np.zeros((0, n))
    D = np.array(rows_D) if rows_D else np.zeros((0, n_inputs))
    return SensorOutputs(C=C, D=D, labels=tuple(labels))


@dataclass(frozen=True)
class KalmanDesign:
    """A steady-state Kalman gain: ``L`` (n x p), the error covariance ``P`` (n x n) and the
    estimator poles ``eig(A - L C)``, sorted."""

    L: np.ndarray
    P: np.ndarray
    poles: np.ndarray


def _noise_args(A: np.ndarray, G: np.ndarray, C: np.ndarray, Q: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, ...]:
    A, C = _check(A, C)
    G = np.atleast_2d(np.asarray(G, dtype=float))
    Q = np.atleast_2d(np.asarray(Q, dtype=float))
    R = np.atleast_2d(np.asarray(R, dtype=float))
    n, p = A.shape[0], C.shape[0]
    if G.shape[0] != n:
        raise DesignError(f"G must have {n} rows, got shape {G.shape}")
    if Q.shape != (G.shape[1], G.shape[1]):
        raise DesignError(f"Q_N must have shape ({G.shape[1]}, {G.shape[1]}), got {Q.shape}")
    if R.shape != (p, p):
        raise DesignError(f"R_N must have shape ({p}, {p}), got {R.shape}")
    if np.any(np.linalg.eigvalsh(R) <= 0.0):
        raise DesignError("R_N must be positive definite (every sensor has noise)")
    return A, G, C, Q, R


def kalman(A: np.ndarray, G: np.ndarray, C: np.ndarray, Q_N: np.ndarray, R_N: np.ndarray) -> KalmanDesign:
    """Continuous steady-state Kalman gain (``control.lqe``; module docstring).

    Fails with :class:`DesignError` when ``(A, C)`` is not detectable (an unobservable mode that is
    not stable, such as the horizontal position of the hover: nothing can bound its error).
    """
    import control

    A, G, C, Q, R = _noise_args(A, G, C, Q_N, R_N)
    try:
        L, P, _ = control.lqe(A, G, C, Q, R)
    except Exception as exc:  # python-control raises several types for a singular Riccati equation
        raise DesignError(f"Kalman gain failed (is (A, C) detectable?): {' '.join(str(exc).split())}") from None
    L = np.asarray(L, dtype=float)
    return KalmanDesign(L=L, P=np.asarray(P, dtype=float), poles=closed_loop_poles(A.T, C.T, L.T))


def discrete_kalman(A: np.ndarray, G: np.ndarray, C: np.ndarray, Q: np.ndarray, R: np.ndarray, dt: float) -> KalmanDesign:
    """Steady-state gain of the filter sampled every ``dt`` [s] (``control.dlqe``).

    The model is discretised by the zero-order hold: ``Phi = exp(A dt)``, and the process noise of
    density ``Q`` becomes ``Q_d = G Q G^T dt`` to first order in ``dt`` (Gelb 1974, eq 3.9-4); ``R``
    is the per-sample covariance ``sigma^2``. ``L`` is the update gain of ``x+ = x- + L (y - C x-)``;
    ``poles`` are the eigenvalues of ``Phi - Phi L C`` (inside the unit circle).
    """
    import control
    from scipy.linalg import expm

    if not (np.isfinite(dt) and dt > 0.0):
        raise DesignError(f"dt must be a finite number > 0 s, got {dt!r}")
    A, G, C, Q, R = _noise_args(A, G, C, Q, R)
    Phi = expm(A * dt)
    n = A.shape[0]
    try:
        L, P, _ = control.dlqe(Phi, np.eye(n), C, G @ Q @ G.T * dt, R)
    except Exception as exc:
        raise DesignError(f"discrete Kalman gain failed (is (A, C) detectable?): {' '.join(str(exc).split())}") from None
    L = np.asarray(L, dtype=float)
    p = np.linalg.eigvals(Phi - Phi @ L @ C)
    return KalmanDesign(L=L, P=np.asarray(P, dtype=float), poles=p[np.lexsort((p.imag, p.real))])


@dataclass(frozen=True)
class LQGDesign:
    """A regulator ``K`` and estimator ``L`` joined (module docstring).

    ``A_cl`` is the closed loop in ``(x, x_hat)``; ``poles`` its eigenvalues, ``regulator_poles``
    ``eig(A - B K)``, ``estimator_poles`` ``eig(A - L C)``, all sorted.
    """

    K: np.ndarray
    L: np.ndarray
    A_cl: np.ndarray
    poles: np.ndarray
    regulator_poles: np.ndarray
    estimator_poles: np.ndarray


def lqg_closed_loop(A: np.ndarray, B: np.ndarray, C: np.ndarray, K: np.ndarray, L: np.ndarray) -> np.ndarray:
    """``[[A, -B K], [L C, A - B K - L C]]``: plant and estimator in ``(x, x_hat)`` with ``u = -K x_hat``."""
    A, C = _check(A, C)
    B = np.atleast_2d(np.asarray(B, dtype=float))
    BK, LC = B @ np.asarray(K, float), np.asarray(L, float) @ C
    return np.block([[A, -BK], [LC, A - BK - LC]])


def lqg(A: np.ndarray, B: np.ndarray, C: np.ndarray, Q: np.ndarray, R: np.ndarray,
        G: np.ndarray, Q_N: np.ndarray, R_N: np.ndarray) -> LQGDesign:
    """LQR gain for weights ``Q``, ``R`` (:func:`.gains.lqr`) and Kalman gain for noise densities
    ``Q_N``, ``R_N`` entering through ``G`` (:func:`kalman`), and their closed loop."""
    reg = lqr(A, B, Q, R)
    est = kalman(A, G, C, Q_N, R_N)
    A_cl = lqg_closed_loop(A, B, C, reg.K, est.L)
    p = np.linalg.eigvals(A_cl)
    return LQGDesign(K=reg.K, L=est.L, A_cl=A_cl, poles=p[np.lexsort((p.imag, p.real))],
                     regulator_poles=reg.poles, estimator_poles=est.poles)
