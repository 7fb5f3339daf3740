"""The navigation filter fed tick by tick from the sensors' messages: what the estimator node runs.

The simulator publishes, for every physics step of a control tick, the sensors its schedule says
are due (:class:`lander_sim.sensors.suite.SampleSchedule`), a due sample with no measurement
included as a "no reading" (docs/sim_node.md, "Sensors"); the IMU is due at every step. So which
readings a control tick at ``t_k`` brings is known in advance:

* the IMU readings stamped in ``(t_(k-1), t_k]``, the last one stamped ``t_k`` (one writer, in
  order: once it is in, every earlier one is);
* at each IMU stamp ``t_i``, every other sensor the schedule makes due at ``t_i``.

:class:`TickFeeder` buffers readings per sensor as they come, says when a tick's are all in
(:meth:`TickFeeder.ready`), and then applies them in one fixed order (time, then the sensor table's
order), so the estimate does not depend on the order in which messages of different sensors
arrive. At each step ``t_i``::

    propagate(omega_m, f_m, t_i - t_(i-1)) with the IMU reading at t_i (none at the first, t = 0)
    -> update with each other sensor due at t_i that gave a measurement

The same steps as :func:`lander_autopilot.estimation.flights.fly` (which skips the instant ``t =
0``; here its aiding readings are used). Times are integer nanoseconds, as the messages carry
them: the propagation's ``dt`` is their difference times 1e-9.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from lander_sim.physics import rotation
from lander_sim.sensors.suite import SampleSchedule, SensorsConfig

from .ekf import EstimationError, NavFilter, Update


@dataclass(frozen=True)
class Reading:
    """One sensor message: sensor ``key``, stamp ``t_ns`` [ns of sim time], value ``z`` and noise
    ``sigma`` (as :class:`lander_sim.sensors.base.Measurement`); both None for a "no reading"."""

    key: str
    t_ns: int
    z: np.ndarray | None = None
    sigma: np.ndarray | None = None


@dataclass(frozen=True)
class Estimate:
    """The estimate after a tick, in the fields of a ``LanderState``: position ``r_W`` [m], velocity
    ``v_W`` [m/s], attitude ``q`` (world -> body), ZXZ Euler angles [rad], body rate ``omega_B``
    [rad/s] (the last gyro reading less the estimated gyro bias), altitude ``|r| - R`` [m], climb
    rate ``v . r_hat`` [m/s] and ground speed ``|v - (v . r_hat) r_hat|`` [m/s]."""

    t: float
    r_W: np.ndarray
    v_W: np.ndarray
    q: np.ndarray
    euler: np.ndarray
    omega_B: np.ndarray
    altitude: float
    climb_rate: float
    ground_speed: float


class TickFeeder:
    """One :class:`NavFilter` fed from readings, a control tick at a time (module docstring).

    ``sensors``: the scene's sensors (rates: the schedule; the altimeter's beam). Start it with
    :meth:`start` (the filter at the flight's first instant), :meth:`add` every reading, and when
    :meth:`ready` says a tick's readings are in, :meth:`advance` to it. Counts: ``dropouts`` (no
    readings, per sensor), ``unexpected`` (a reading whose stamp is no due instant of its sensor,
    dropped), ``unused`` (readings at a step without an IMU reading), ``rejected`` (bad values
    refused by the filter, whose ``EstimationError`` text is kept in ``last_error``)."""

    def __init__(self, sensors: SensorsConfig) -> None:
        if "imu" not in sensors.sections:
            raise ValueError("the estimator needs sensors.imu switched on: the filter propagates on it")
        self.sensors = sensors
        self.rates = {key: float(v["rate"]) for key, v in sensors.sections.items()}
        beam = sensors.sections.get("altimeter", {}).get("beam_B")
        self.beam_B = None if beam is None else np.array(beam, float)
        self.filter: NavFilter | None = None
        self.reset()

    def reset(self) -> None:
        """Forget the flight: no filter, empty buffers, the schedule at ``t = 0``."""
        self.queues: dict[str, deque[Reading]] = {key: deque() for key in self.rates}
        self._last_added: dict[str, int | None] = dict.fromkeys(self.rates)
        self._first_of_flight: dict[str, Reading | None] = dict.fromkeys(self.rates)
        self.restart()

    def restart(self) -> None:
        """A new flight (the simulator was reset): no filter, the schedule at ``t = 0``, and of the
        buffered readings only those of the new flight (see :meth:`add`)."""
        for key, first in self._first_of_flight.items():
            q = self.queues[key]
            while q and q[0] is not first:
                q.popleft()
        self._first_of_flight = dict.fromkeys(self.rates)
        self.filter = None
        self.schedule = SampleSchedule(self.rates)
        self.t_ns: int | None = None  # stamp of the last IMU reading applied
        self.omega_m = np.zeros(3)
        #: Variance [rad^2/s^2] of the gyro reading ``omega_m`` (the last IMU reading applied; 0 before one).
        self.omega_var = np.zeros(3)
        self.updates = 0
        self.dropouts = dict.fromkeys(self.rates, 0)
        self.unexpected = 0
        self.unused = 0
        self.rejected = 0
        self.last_error = ""

    def start(self, filt: NavFilter) -> None:
        """Fly this filter from now on (its state at the flight's first instant)."""
        self.filter = filt

    def add(self, reading: Reading) -> None:
        """Buffer one reading; a sensor the scene does not switch on is counted unexpected.

        One sensor's stamps increase within a flight, so a stamp not after the sensor's previous
        one may start a new flight (a reset, whose readings at ``t = 0`` go out before its first
        state): it is remembered, and :meth:`restart` keeps the readings from it on. Without a
        restart it is a stale reading, which :meth:`advance` drops and counts."""
        q = self.queues.get(reading.key)
        if q is None:
            self.unexpected += 1
            return
        last = self._last_added[reading.key]
        if last is not None and reading.t_ns <= last:
            self._first_of_flight[reading.key] = reading
        self._last_added[reading.key] = reading.t_ns
        q.append(reading)

    def _steps(self, sched: SampleSchedule, t_ns: int) -> list[tuple[int, Reading | None, list[str]]] | None:
        """The steps of the tick at ``t_ns`` as ``(stamp, IMU reading or None, other sensors due)``,
        advancing ``sched``; None while an IMU reading of the tick is still to come. Every IMU
        reading stamped up to ``t_ns`` is a step; ``t_ns`` itself is a step without one when the
        schedule does not make the IMU due there (the flight's last, partial step at a touchdown)."""
        out: list[tuple[int, Reading | None, list[str]]] = []
        last = None
        for r in self.queues["imu"]:
            if r.t_ns > t_ns:
                continue  # a later tick's
            due = sched.due(r.t_ns * 1e-9)
            if "imu" not in due:
                continue  # off its schedule: advance() drops it
            out.append((r.t_ns, r, [k for k in due if k != "imu"]))
            last = r.t_ns
        if last != t_ns and (self.t_ns is None or t_ns > self.t_ns):
            due = sched.due(t_ns * 1e-9)
            if "imu" in due:
                return None
            out.append((t_ns, None, due))
        return out

    def ready(self, t_ns: int) -> bool:
        """Whether every reading the tick at ``t_ns`` brings is in (module docstring)."""
        steps = self._steps(self.schedule.copy(), t_ns)
        if steps is None:
            return False
        pos = dict.fromkeys(self.queues, 0)
        for t_i, _, keys in steps:
            for key in keys:
                queue, q = self.queues[key], pos[key]
                while q < len(queue) and queue[q].t_ns < t_i:
                    q += 1  # a stale reading: advance() drops it
                if q >= len(queue):
                    return False
                pos[key] = q + 1 if queue[q].t_ns == t_i else q
        return True

    def advance(self, t_ns: int) -> list[Update]:
        """Apply every reading up to the tick at ``t_ns`` (call when :meth:`ready`); the updates made.
        At a step without an IMU reading the filter is not propagated, and that step's other
        readings are taken off their queues unused (counted in ``unused``)."""
        if self.filter is None:
            raise RuntimeError("TickFeeder.advance before start")
        steps = self._steps(self.schedule, t_ns)
        if steps is None:
            raise RuntimeError(f"TickFeeder.advance({t_ns}) before its readings are in")
        used = [s[1] for s in steps]
        later = deque(r for r in self.queues["imu"] if r.t_ns > t_ns)
        # an IMU reading of this tick off its schedule (a stale stamp) is not used
        self.unexpected += len(self.queues["imu"]) - len(later) - sum(r is not None for r in used)
        self.queues["imu"] = later
        out: list[Update] = []
        for t_i, r, keys in steps:
            if r is not None:
                self._propagate(r)
            for key in keys:
                u = self._aid(key, t_i, use=r is not None)
                if u is not None:
                    out.append(u)
        return out

    def estimate(self) -> Estimate:
        """The estimate now (:class:`Estimate`)."""
        if self.filter is None:
            raise RuntimeError("TickFeeder.estimate before start")
        s = self.filter.state
        r, v = s.r_W, s.v_W
        rn = math.sqrt(float(r @ r))
        climb = float(v @ r) / rn
        h = v - (climb / rn) * r
        return Estimate(t=s.t, r_W=r.copy(), v_W=v.copy(), q=s.q.copy(), euler=rotation.quat_to_euler(s.q),
                        omega_B=self.omega_m - s.b_g, altitude=rn - self.filter.planet_radius, climb_rate=climb,
                        ground_speed=math.sqrt(float(h @ h)))

    def _propagate(self, r: Reading) -> None:
        assert self.filter is not None
        if r.z is None or r.sigma is None:
            self.dropouts["imu"] += 1
            return
        if self.t_ns is not None:
            try:
                self.filter.propagate(r.z[0:3], r.z[3:6], (r.t_ns - self.t_ns) * 1e-9)
            except EstimationError as exc:
                self._refused(exc)
                return
        self.t_ns = r.t_ns
        self.omega_m = np.asarray(r.z[0:3], float)
        if r.sigma is not None:
            self.omega_var = np.asarray(r.sigma[0:3], float) ** 2

    def _aid(self, key: str, t_ns: int, use: bool = True) -> Update | None:
        assert self.filter is not None
        queue = self.queues[key]
        while queue and queue[0].t_ns < t_ns:
            queue.popleft()
            self.unexpected += 1
        if not queue or queue[0].t_ns != t_ns:
            return None  # none at this instant (ready() waited for a later one): nothing to apply
        r = queue.popleft()
        if not use:
            self.unused += 1
            return None
        if r.z is None or r.sigma is None:
            self.dropouts[key] += 1
            return None
        f = self.filter
        u: Update | None
        try:
            if key == "star_tracker":
                u = f.update_star_tracker(r.z, r.sigma)
            elif key == "altimeter":
                beam = self.beam_B if self.beam_B is not None else np.array([0.0, 0.0, -1.0])
                u = f.update_altimeter(float(r.z[0]), float(r.sigma[0]), beam)
            elif key == "doppler":
                u = f.update_doppler(r.z, r.sigma)
            else:
                u = f.update_ground_fix(r.z, r.sigma)
        except EstimationError as exc:
            self._refused(exc)
            return None
        if u is not None:
            self.updates += 1
        return u

    def _refused(self, exc: EstimationError) -> None:
        self.rejected += 1
        self.last_error = str(exc)
