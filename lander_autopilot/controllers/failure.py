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
"""
from __future__ import annotations

import numpy as np

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

    def observe(self, t: float, omega_B: np.ndarray, fuel: float) -> int | None:
        """Take this update's body rate; compare with the last period's commanded torque."""
        omega = np.array(omega_B, dtype=float)
        if self.failed is None and self._last is not None:
            t0, w0, u0 = self._last
            dt = t - t0
            if dt > 0.0:
                I = self.vehicle.inertia(fuel)
                w = 0.5 * (w0 + omega)
                gyro = np.cross(I * w, w)  # (I w) x w
                tau = u0 @ self.torque_per_throttle
                r = I * (omega - w0) / dt - gyro - tau
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
        return self.failed

    def commanded(self, throttles: np.ndarray) -> None:
        """The throttles sent for the coming period (after clipping)."""
        if self._last is not None:
            self._last = (self._last[0], self._last[1], np.array(throttles, dtype=float))


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
