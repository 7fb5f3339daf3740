"""Thruster-failure detection from the state alone, and the three-thruster allocation that flies on.

**Detection.** The autopilot never reads the simulator's failure flags. It sees the body rate
``omega`` at every update and knows the throttles it commanded over the last period, so it can
compare the measured angular acceleration with the one the thrusters should have produced
(Euler's equations, ``I = m diag(k^2)`` at the current fuel)::

    r = I (omega_k - omega_{k-1}) / dt - (I omega) x omega - tau(u_{k-1}),   tau(u) = -sum_i s_i u_i T_i

A thruster ``i`` that gives nothing leaves ``r = g_i = s_i u_i T_i`` (its missing torque). With
exponential forgetting the detector accumulates, per thruster, ``S_i = sum r . g_i`` and
``N_i = sum |g_i|^2``; ``S_i / N_i`` is the fraction of thruster ``i``'s torque that is missing
(least squares, one thruster at a time). A thruster is declared failed when that fraction is
above ``fraction`` (0.6), the fit explains most of the residual (``S_i^2 / N_i`` above
``explained`` (0.8) of ``sum |r|^2``) and the evidence is large enough (``N_i`` above the torque
of ``min_torque`` N m over ``min_evidence`` s). Thrust and inertia errors of a few per cent
give fractions of a few per cent; the parachute's restoring torque and the gyroscopic terms are
small against a whole thruster at the throttles the landing law brakes with. The decision is
latched (a failed thruster does not come back in the simulator).

**Allocation with three thrusters.** Four canted thrusters give roll, pitch, yaw and lift; three
cannot hold all four, and attitude priority then keeps the yaw demand and starves the lift. The
lander does not need its heading to land, so after a failure the law gives yaw up: the remaining
thrusters ``j`` solve ``[tau_x, tau_y, F_z] = M t`` exactly (``M`` 3x3, invertible for any one
thruster lost), the attitude law's roll and pitch torque keep priority over the lift, and the yaw
torque is let be (the lander spins up about its axis; the attitude demand follows the
current heading so the spin is no error).

**Under the parachute** the canopy's torque is part of the model (:class:`ChuteTorqueModel`:
the simulator's formula, the wind learnt from the residual while the thrusters rest), passed to
:meth:`ThrusterFailureDetector.observe` as the external torque.

**Spinning** (:class:`SpinAllocation`): a long braking on the pair alone spins the lander up past
what a 10 Hz law follows; spinning, the lone thruster may fire too, since its roll/pitch torque
turns with the body. The three throttles then hold lift, yaw torque and the torque along the
pair's axis exactly.
"""
from __future__ import annotations

import math

import numpy as np

from lander_sim.physics import constants as c
from lander_sim.physics.models.atmosphere import MARS_ATMOSPHERE
from lander_sim.physics.rotation import quat_to_matrix
from lander_sim.physics.state import StateView
from lander_sim.physics.vehicle import Vehicle


class ThrusterFailureDetector:
    """Latches the index of a thruster whose torque is missing (module docstring); ``None`` until then."""

    def __init__(
        self,
        vehicle: Vehicle,
        *,
        fraction: float = 0.6,
        explained: float = 0.8,
        forgetting_time: float = 0.1,
        min_torque: float = 30.0,
        min_evidence: float = 0.1,
    ) -> None:
        self.vehicle = vehicle
        self.fraction = fraction
        self.explained = explained
        self.forgetting_time = forgetting_time
        self.min_N = min_torque * min_torque * min_evidence
        T = np.array([th.max_thrust if th.enabled else 0.0 for th in vehicle.thrusters])
        #: Torque per unit throttle of each thruster, body frame [N m], shape (N, 3).
        self.torque_per_throttle = -vehicle.torque_arms() * T[:, None]
        self.reset()

    def reset(self) -> None:
        self.failed: int | None = None
        self.failed_at: float | None = None
        n = self.vehicle.n_thrusters
        self._S = np.zeros(n)
        self._N = np.zeros(n)
        self._E = 0.0
        self._last: tuple[float, np.ndarray, np.ndarray] | None = None
        self._last_external = np.zeros(3)
        #: The last period's residual torque, body frame [N m] (zeros until there is one).
        self.residual = np.zeros(3)
        #: The throttles the last residual was computed with (what the thrusters were asked for).
        self.residual_throttles = np.zeros(self.vehicle.n_thrusters)

    def observe(self, t: float, omega_B: np.ndarray, fuel: float, external_torque: np.ndarray | None = None) -> int | None:
        """Take this update's body rate; compare with the last period's commanded torque.

        ``external_torque``: the known torque of everything but the thrusters at this instant, body
        frame [N m] (the open parachute's); the period's is taken as the mean of its two ends.
        """
        omega = np.array(omega_B, dtype=float)
        ext = np.zeros(3) if external_torque is None else np.asarray(external_torque, dtype=float)
        if self.failed is None and self._last is not None:
            t0, w0, u0 = self._last
            dt = t - t0
            if dt > 0.0:
                I = self.vehicle.inertia(fuel)
                w = 0.5 * (w0 + omega)
                gyro = np.cross(I * w, w)  # (I w) x w
                tau = u0 @ self.torque_per_throttle + 0.5 * (ext + self._last_external)
                r = I * (omega - w0) / dt - gyro - tau
                self.residual = r
                self.residual_throttles = u0
                G = self.torque_per_throttle * u0[:, None]  # g_i = s_i u_i T_i: each thruster's missing torque
                decay = float(np.exp(-dt / self.forgetting_time))
                self._S = decay * self._S - G @ r * dt
                self._N = decay * self._N + np.einsum("ij,ij->i", G, G) * dt
                self._E = decay * self._E + float(r @ r) * dt
                with np.errstate(divide="ignore", invalid="ignore"):
                    frac = np.where(self._N > 0.0, self._S / np.maximum(self._N, 1e-300), 0.0)
                i = int(np.argmax(frac))
                if (self._N[i] > self.min_N and frac[i] > self.fraction
                        and self._S[i] * frac[i] > self.explained * self._E):
                    self.failed = i
                    self.failed_at = t
        self._last = (t, omega, self._last[2] if self._last is not None else np.zeros(self.vehicle.n_thrusters))
        self._last_external = ext
        return self.failed

    def commanded(self, throttles: np.ndarray) -> None:
        """The throttles sent for the coming period (after clipping)."""
        if self._last is not None:
            self._last = (self._last[0], self._last[1], np.array(throttles, dtype=float))


class ChuteTorqueModel:
    """The open parachute's torque on the lander, body frame [N m], as the simulator models it, with
    the horizontal wind estimated from the torque the model leaves unexplained.

    The canopy pulls ``F = 1/2 rho Cd pi r^2 |W| W`` at ``a = (0, 0, L/2)`` (body frame), with
    ``W = R (w - v) - omega x a`` the air velocity at the attachment point; its torque ``a x F``
    has no body-z part, so the yaw residual never depends on it. Under the canopy at 40 m/s that
    torque is ~380 N m per radian of tilt and ~10 N m per m/s of horizontal wind: the tilt and rate
    parts are known from the state, the wind part is not. While the thrusters are quiet (every
    throttle under ``quiet_throttle``, so a dead one could hide at most ~10 N m) the residual is
    the wind's: with ``a = (0, 0, a_z)`` it is ``a_z (-dF_y, dF_x)``, and across the flow
    ``dF = 1/2 rho Cd pi r^2 |W| dw``, so the estimate ``w`` (world frame [m/s]) moves towards the
    wind that explains it with time constant ``time_constant`` [s] (the gusts' is 2 s). It is held
    while the thrusters work, so a failed thruster's torque is never taken for wind.
    """

    def __init__(self, vehicle: Vehicle, *, quiet_throttle: float = 0.05, time_constant: float = 1.0) -> None:
        self.vehicle = vehicle
        self.attach_B = np.array([0.0, 0.0, 0.5 * vehicle.size])
        self.k = 0.5 * c.PARACHUTE_DRAG_COEFFICIENT * math.pi * c.PARACHUTE_RADIUS**2  # [m^2]
        self.quiet_throttle = quiet_throttle
        self.time_constant = time_constant
        self.reset()

    def reset(self) -> None:
        #: Estimated wind, world frame [m/s].
        self.wind_W = np.zeros(3)

    def _air(self, state: StateView) -> tuple[np.ndarray, np.ndarray, float]:
        R = quat_to_matrix(state.q)  # world -> body
        W = R @ (self.wind_W - state.v_W) - np.cross(state.omega_B, self.attach_B)
        h = float(np.linalg.norm(state.r_W)) - c.MARS_RADIUS
        return R, W, self.k * MARS_ATMOSPHERE.density(h) * float(np.linalg.norm(W))

    def torque(self, state: StateView) -> np.ndarray:
        """The canopy's torque at ``state`` with the estimated wind, body frame [N m]."""
        _, W, s = self._air(state)
        return np.cross(self.attach_B, s * W)

    def learn(self, residual_B: np.ndarray, throttles: np.ndarray, state: StateView, dt: float) -> None:
        """Move the wind estimate towards the wind that explains ``residual_B`` (body frame [N m],
        the last period's), if the thrusters were quiet over that period (``throttles``)."""
        if dt <= 0.0 or float(np.max(throttles, initial=0.0)) > self.quiet_throttle:
            return
        R, _, s = self._air(state)
        if s <= 0.0:
            return
        a_z = float(self.attach_B[2])
        dw_B = np.array([residual_B[1] / a_z, -residual_B[0] / a_z, 0.0]) / s
        self.wind_W = self.wind_W + min(dt / self.time_constant, 1.0) * (R.T @ dw_B)


class ThreeThrusterAllocation:
    """Throttles for the thrusters left after ``failed``: roll and pitch torque exactly, then lift."""

    def __init__(self, vehicle: Vehicle, failed: int) -> None:
        n = vehicle.n_thrusters
        self.n = n
        self.failed = failed
        self.working = [j for j in range(n) if j != failed and vehicle.thrusters[j].enabled]
        T = np.array([th.max_thrust for th in vehicle.thrusters])
        tau = -vehicle.torque_arms() * T[:, None]  # (N, 3) body torque per unit throttle
        fz = np.array([-th.direction_B[2] * th.max_thrust for th in vehicle.thrusters])  # body z force per unit throttle
        self.tau = tau
        self.fz = fz
        M = np.vstack([tau[self.working, 0], tau[self.working, 1], fz[self.working]])
        self.M_inv = np.linalg.inv(M)
        self.lift_direction = self.M_inv @ np.array([0.0, 0.0, 1.0])  # throttles per newton of lift, no roll/pitch
        #: Largest body-z force with no roll or pitch torque [N].
        self.max_lift = 1.0 / float(np.max(self.lift_direction[self.lift_direction > 0.0]))

    def allocate(self, torque_xy: np.ndarray, lift: float) -> tuple[np.ndarray, bool]:
        """Throttles (all N, the failed one 0) and whether the lift had to give way."""
        t_att = self.M_inv @ np.array([torque_xy[0], torque_xy[1], 0.0])
        d = self.lift_direction
        # t = t_att + F d, each in [0, 1]: the range of F; the torque keeps priority.
        lo, hi = -np.inf, np.inf
        for ta, dj in zip(t_att, d):
            if dj > 1e-12:
                lo, hi = max(lo, -ta / dj), min(hi, (1.0 - ta) / dj)
            elif dj < -1e-12:
                lo, hi = max(lo, (1.0 - ta) / dj), min(hi, -ta / dj)
        saturated = False
        if lo > hi:  # the torque alone does not fit: shrink it about the middle of the lift range
            s = 1.0
            for _ in range(30):
                s *= 0.8
                lo2, hi2 = -np.inf, np.inf
                for ta, dj in zip(s * t_att, d):
                    if dj > 1e-12:
                        lo2, hi2 = max(lo2, -ta / dj), min(hi2, (1.0 - ta) / dj)
                    elif dj < -1e-12:
                        lo2, hi2 = max(lo2, (1.0 - ta) / dj), min(hi2, -ta / dj)
                if lo2 <= hi2:
                    break
            t_att, lo, hi = s * t_att, lo2, hi2
            saturated = True
        F = min(max(lift, lo), hi)
        saturated = saturated or F != lift
        t = t_att + F * d
        # The lone thruster (opposite the failed one) does not lift: a torque that needs it below 0
        # is out of reach whatever the lift, and is clipped (the yaw spin-up turns it into reach).
        saturated = saturated or bool(np.any(t < -1e-9) or np.any(t > 1.0 + 1e-9))
        u = np.zeros(self.n)
        u[self.working] = np.clip(t, 0.0, 1.0)
        return u, saturated


def _keep_then_fit(kept: float, c_kept: np.ndarray, fitted: float, c_fitted: np.ndarray) -> tuple[float, float]:
    """The first wish kept (clipped only if the throttles cannot give it at all), then the second
    clipped into what the first leaves: ``(kept, fitted)``."""
    lo, hi = _interval(kept * c_kept, c_fitted)
    if lo > hi:
        lo, hi = _interval(np.zeros(3), c_kept)
        kept = min(max(kept, lo), hi)
        lo, hi = _interval(kept * c_kept, c_fitted)
    return kept, min(max(fitted, lo), hi)


def _interval(t0: np.ndarray, d: np.ndarray, top: np.ndarray | None = None) -> tuple[float, float]:
    """The range of ``s`` with every ``t0 + s d`` in [0, top] (top 1 if not given; empty: lo > hi)."""
    lo, hi = -np.inf, np.inf
    for j, (a, b) in enumerate(zip(t0, d)):
        ub = 1.0 if top is None else float(top[j])
        if b > 1e-12:
            lo, hi = max(lo, -a / b), min(hi, (ub - a) / b)
        elif b < -1e-12:
            lo, hi = max(lo, (ub - a) / b), min(hi, -a / b)
        elif a < -1e-12 or a > ub + 1e-12:
            return np.inf, -np.inf
    return lo, hi


class SpinAllocation:
    """Throttles for the three thrusters left when the lander spins about its axis.

    Of the three, two (the *pair*, diagonal to each other) have yaw torques of one sign, the third
    (the *lone* one) of the other. With no roll or pitch torque only the pair can fire, and the
    pair alone spins the lander up (about 1.4 rad/s^2 at full throttle): on a long braking the spin
    would grow past anything a 10 Hz law (and the simulator's 0.1 s step) follows. Spinning, the
    lone thruster's own roll/pitch torque ``tau_L`` is fixed in the body and turns with it: its
    mean over a turn is zero and it only makes the axis cone, by ``tau_L / ((I_t - I_z) Omega^2)``
    [rad] (2 deg at 218 N m, 14 rad/s, 190 kg). So, spinning, the lone thruster may fire: the three
    throttles solve exactly for the lift, the yaw torque (which holds the spin) and the roll/pitch
    torque along the pair's differential axis ``e_P`` (which steers the spin axis); the torque
    across it is the lone thruster's, left to the spin to average.
    """

    def __init__(self, vehicle: Vehicle, failed: int) -> None:
        n = vehicle.n_thrusters
        self.n = n
        self.working = [j for j in range(n) if j != failed and vehicle.thrusters[j].enabled]
        T = np.array([th.max_thrust for th in vehicle.thrusters])
        tau = -vehicle.torque_arms() * T[:, None]  # (N, 3) body torque per unit throttle [N m]
        fz = np.array([-th.direction_B[2] * th.max_thrust for th in vehicle.thrusters])  # [N] per unit throttle
        signs = np.sign(tau[self.working, 2])
        lone = [j for j, s in zip(self.working, signs) if np.sum(signs == s) == 1]
        if len(self.working) != 3 or len(lone) != 1:
            raise ValueError("SpinAllocation needs three thrusters left, two with yaw torques of one sign")
        self.lone = lone[0]
        self.pair = [j for j in self.working if j != self.lone]
        d = tau[self.pair[0], :2] - tau[self.pair[1], :2]
        #: The pair's differential torque axis (body x-y), the one roll/pitch direction held exactly.
        self.e_P = d / float(np.linalg.norm(d))
        #: Sign of the pair's yaw torque: the way the pair spins the lander.
        self.pair_spin = float(np.sign(tau[self.pair[0], 2]))
        M = np.vstack([tau[self.working, :2] @ self.e_P, fz[self.working], tau[self.working, 2]])
        self.M_inv = np.linalg.inv(M)
        self.fz = fz
        self.tau = tau
        #: Lift [N] with the three at full throttle (the spin then grows), and with zero yaw torque.
        self.max_lift = float(fz[self.working].sum())
        t0 = self.M_inv[:, 1]
        lo, hi = _interval(np.zeros(3), t0)
        self.max_lift_no_yaw = hi

    def allocate(self, torque_p: float, lift: float, yaw: float, yaw_first: bool = False,
                 lone_max: float = 1.0) -> tuple[np.ndarray, bool]:
        """Throttles (all N, the failed one 0) for the torque ``torque_p`` [N m] along ``e_P``, the
        body-z force ``lift`` [N] and the yaw torque ``yaw`` [N m]; lift before yaw unless ``yaw_first``,
        both before ``torque_p``; the yaw also gives way to keep the lone thruster at or below
        ``lone_max``. Also whether anything gave way."""
        cP, cF, cY = self.M_inv[:, 0], self.M_inv[:, 1], self.M_inv[:, 2]
        lift0, yaw0, tp0 = lift, yaw, torque_p
        if lone_max < 1.0 and not yaw_first:
            top = np.array([lone_max if j == self.lone else 1.0 for j in self.working])
            lo, hi = _interval(lift * cF, cY, top)
            if lo <= hi:
                yaw = min(max(yaw, lo), hi)
        if yaw_first:
            yaw, lift = _keep_then_fit(yaw, cY, lift, cF)
        else:
            lift, yaw = _keep_then_fit(lift, cF, yaw, cY)
        base = lift * cF + yaw * cY
        lo, hi = _interval(base, cP)
        torque_p = min(max(torque_p, lo), hi) if lo <= hi else 0.0
        u = np.zeros(self.n)
        u[self.working] = np.clip(base + torque_p * cP, 0.0, 1.0)
        return u, bool(lift != lift0 or yaw != yaw0 or torque_p != tp0)
