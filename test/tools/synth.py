"""Synthetic flight bags written with the rosbags Writer (no rclpy): closed-form trajectories
whose metrics are known from theory, for testing bag reading and analysis on their own."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from lander_sim.physics.constants import MARS_RADIUS
from lander_tools.bagio import lander_typestore

STATE = "lander_interfaces/msg/LanderState"
STATUS = "lander_interfaces/msg/AutopilotStatus"
EVENT = "lander_interfaces/msg/FlightEvent"
ODOM = "nav_msgs/msg/Odometry"


def _odometry(T, stamp, est: dict[str, np.ndarray], i: int):
    """Row ``i`` of ``est`` as the estimator node's Odometry (pose in mars, twist in base_link)."""
    r, q, v = est["r_W"][i], est["q"][i], est["v_B"][i]
    V3, H = T["geometry_msgs/msg/Vector3"], T["std_msgs/msg/Header"]
    pose = T["geometry_msgs/msg/PoseWithCovariance"](
        pose=T["geometry_msgs/msg/Pose"](position=T["geometry_msgs/msg/Point"](x=r[0], y=r[1], z=r[2]),
                                         orientation=T["geometry_msgs/msg/Quaternion"](x=q[1], y=q[2], z=q[3], w=q[0])),
        covariance=np.asarray(est["pose_cov"][i], dtype=float))
    twist = T["geometry_msgs/msg/TwistWithCovariance"](
        twist=T["geometry_msgs/msg/Twist"](linear=V3(x=v[0], y=v[1], z=v[2]), angular=V3(x=0.0, y=0.0, z=0.0)),
        covariance=np.asarray(est["twist_cov"][i], dtype=float))
    return T[ODOM](header=H(stamp=stamp, frame_id="mars"), child_frame_id="base_link", pose=pose, twist=twist)


def write_flight_bag(
    path: Path,
    t: np.ndarray,
    altitude: np.ndarray,
    climb_rate: np.ndarray,
    demand: list[tuple[float, float]] = (),
    omega_B: np.ndarray | None = None,
    q: np.ndarray | None = None,
    throttles: np.ndarray | None = None,
    fuel: np.ndarray | None = None,
    storage: str = "mcap",
    meta: dict[str, str] | None = None,
    status_demand: np.ndarray | None = None,
    phase: np.ndarray | None = None,
    euler: np.ndarray | None = None,
    gimbal_lock: np.ndarray | None = None,
    stabiliser: np.ndarray | None = None,
    status_mode: np.ndarray | None = None,
    status_saturated: np.ndarray | None = None,
    events: list[tuple[float, int]] | None = None,
    estimate: dict[str, np.ndarray] | None = None,
) -> None:
    """A bag with /clock, /lander/state (upright lander on the -y axis, as scene 'hover') and
    /lander/demand_altitude; bag time = sim time + 1 s (so the /clock mapping is exercised).
    With ``status_demand`` (one value per state) also /autopilot/status carrying that demand in force;
    ``phase`` (one per state, default 0: flying) is the state's phase field (1 landed, 2 crashed);
    ``euler`` (N, 3), ``gimbal_lock`` and ``stabiliser`` (N,) the state's fields of those names;
    ``status_mode`` and ``status_saturated`` (N,) the status's (with ``status_demand``); ``events``
    ``(t, kind)`` pairs written to /lander/events (``[]`` records the topic with no event).
    ``estimate``: /lander/estimate/odometry at the states' stamps, as the estimator node fills it
    (docs/estimation.md), from arrays of one row per state: ``r_W`` (N, 3), ``q`` (N, 4, core order),
    ``v_B`` (N, 3, body axes), ``pose_cov`` and ``twist_cov`` (N, 36); a state whose ``r_W`` row is
    NaN gets no estimate."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    ts = lander_typestore()
    T = ts.types
    n = len(t)
    omega_B = np.zeros((n, 3)) if omega_B is None else omega_B
    q = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)) if q is None else q
    throttles = np.full((n, 4), 0.5) if throttles is None else throttles
    fuel = np.full(n, 100.0) if fuel is None else fuel
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    offset = 10**9

    def stamp(x: float):
        sec = int(np.floor(x))
        return T["builtin_interfaces/msg/Time"](sec=sec, nanosec=int(round((x - sec) * 1e9)))

    with Writer(path, version=9, storage_plugin=plugin) as w:
        for k, v in (meta or {}).items():
            w.set_custom_data(k, v)
        c_clock = w.add_connection("/clock", "rosgraph_msgs/msg/Clock", typestore=ts)
        c_state = w.add_connection("/lander/state", STATE, typestore=ts)
        c_dem = w.add_connection("/lander/demand_altitude", "std_msgs/msg/Float64", typestore=ts)
        c_status = w.add_connection("/autopilot/status", STATUS, typestore=ts) if status_demand is not None else None
        c_odom = w.add_connection("/lander/estimate/odometry", ODOM, typestore=ts) if estimate is not None else None
        if events is not None:
            c_ev = w.add_connection("/lander/events", EVENT, typestore=ts)
            for te, kind in events:
                ev = T[EVENT](header=T["std_msgs/msg/Header"](stamp=stamp(te), frame_id=""), kind=kind,
                              detail="synthetic", values=np.zeros(0))
                w.write(c_ev, offset + int(round(te * 1e9)), ts.serialize_cdr(ev, EVENT))
        events = sorted(demand)
        for i in range(n):
            tb = offset + int(round(t[i] * 1e9))
            while events and events[0][0] <= t[i] + 1e-12:
                td, hd = events.pop(0)
                w.write(c_dem, offset + int(round(td * 1e9)), ts.serialize_cdr(T["std_msgs/msg/Float64"](data=hd), "std_msgs/msg/Float64"))
            w.write(c_clock, tb, ts.serialize_cdr(T["rosgraph_msgs/msg/Clock"](clock=stamp(t[i])), "rosgraph_msgs/msg/Clock"))
            r = MARS_RADIUS + altitude[i]
            msg = T[STATE](
                header=T["std_msgs/msg/Header"](stamp=stamp(t[i]), frame_id="mars"),
                sequence=i + 1,
                position=T["geometry_msgs/msg/Point"](x=0.0, y=-r, z=0.0),
                velocity=T["geometry_msgs/msg/Vector3"](x=0.0, y=-climb_rate[i], z=0.0),
                orientation=T["geometry_msgs/msg/Quaternion"](x=q[i, 1], y=q[i, 2], z=q[i, 3], w=q[i, 0]),
                euler_zxz=np.array([0.0, np.pi / 2, 0.0]) if euler is None else np.asarray(euler[i], dtype=float),
                gimbal_lock=False if gimbal_lock is None else bool(gimbal_lock[i]),
                angular_velocity=T["geometry_msgs/msg/Vector3"](x=omega_B[i, 0], y=omega_B[i, 1], z=omega_B[i, 2]),
                altitude=float(altitude[i]),
                climb_rate=float(climb_rate[i]),
                ground_speed=0.0,
                mass=100.0 + float(fuel[i]),
                fuel_mass=float(fuel[i]),
                throttles=np.asarray(throttles[i], dtype=float),
                phase=0 if phase is None else int(phase[i]),
                parachute_deployed=False,
                stabiliser_on=False if stabiliser is None else bool(stabiliser[i]),
            )
            w.write(c_state, tb, ts.serialize_cdr(msg, STATE))
            if c_odom is not None and np.all(np.isfinite(estimate["r_W"][i])):
                w.write(c_odom, tb, ts.serialize_cdr(_odometry(T, stamp(t[i]), estimate, i), ODOM))
            if c_status is not None:
                st = T[STATUS](
                    header=T["std_msgs/msg/Header"](stamp=stamp(t[i]), frame_id=""),
                    controller="synthetic", saturated=False if status_saturated is None else bool(status_saturated[i]), steps=i + 1, rejected=0, state_ok=True, last_error="",
                    throttles=np.asarray(throttles[i], dtype=float), demand_altitude=float(status_demand[i]),
                    velocity_demanded=False, demand_velocity=T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
                    mode="" if status_mode is None else str(status_mode[i]),
                )
                w.write(c_status, tb, ts.serialize_cdr(st, STATUS))
