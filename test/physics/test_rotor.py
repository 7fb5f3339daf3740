"""The gimballed rotor of seed 1 (Figure 1) and the gimbal-lock cases of seed 1 task 2."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from lander_sim.physics.events import EventKind
from lander_sim.scenes import load_scene
from lander_sim.simulation import Simulation
from lander_tools.analysis_plots import ztrack_figure
from lander_tools.plotstyle import colour, save

DOC_IMAGE = Path(__file__).resolve().parents[2] / "docs" / "img" / "rotor-z-track.png"


def z_track(scene: str, dt: float | None = None) -> np.ndarray:
    """World coordinates of the body z axis at every step (the seed's ``track(n,:) = R(3,:)``)."""
    sim = Simulation(load_scene(scene), dt=dt)
    n = int(round(sim.scene.end_time / sim.dt))
    track = np.empty((n + 1, 3))
    for k in range(n + 1):
        track[k] = sim.dynamics.rotation_matrix(sim.y)[2]
        if k < n:
            sim.step()
    return track


def plot_z_track(track: np.ndarray, path: Path) -> None:
    """The seed 1 Figure 1 plot: 3-D track of the rotor's z axis (``lander analyse``'s z-track figure;
    ``DOC_IMAGE`` is this figure of ``rotor-quaternion``)."""
    fig = ztrack_figure([("rotor-quaternion", track, colour(0))])
    fig.axes[0].set_title("Gimballed rotor: body z axis in world coordinates\n(precession and nutation)")
    save(fig, path, dpi=90)


def test_rotor_reproduces_figure_1_cuspidal_precession_and_nutation(tmp_path):
    track = z_track("rotor-quaternion")
    out = tmp_path / "rotor-z-track.png"
    plot_z_track(track, out)
    assert out.stat().st_size > 0
    height = track[:, 2]
    azimuth = np.unwrap(np.arctan2(track[:, 1], track[:, 0]))
    # Released with the spin axis horizontal, from rest in precession.
    assert abs(height[0]) < 1e-12
    # Nutation: the axis dips. Theory (fast top): depth ~ 2 A m g l / (C w3)^2 = 0.156 rad.
    assert -0.4 < height.min() < -0.05
    # Cusps: local maxima of the height return to the release height (energy is
    # conserved, and at a cusp all kinetic energy is back in the spin), and there the
    # azimuthal rate vanishes.
    k = np.flatnonzero((height[1:-1] >= height[:-2]) & (height[1:-1] >= height[2:])) + 1
    k = k[k > 5]
    assert len(k) >= 8  # nutation period ~ 2 pi A / (C w3) = 0.79 s: ~12 cusps in 10 s
    depth = -height.min()
    # Verlet's energy error (O(dt^2) ~ 1e-3 relative here) bounds how far the cusps drift.
    assert np.all(np.abs(height[k]) < 0.05 * depth)
    rate = np.gradient(azimuth, 0.01)
    mean_rate = (azimuth[-1] - azimuth[0]) / 10.0
    # sampled every 0.01 s against a ~0.79 s nutation period: the grid misses the
    # exact cusp by <= 0.005 s, where the rate changes by ~ mean * 2 pi * 0.005 / 0.79 ~ 4% of it.
    assert np.all(np.abs(rate[k]) < 0.1 * abs(mean_rate))
    # Precession: monotonic on average, azimuth at successive cusps strictly one way,
    # at the rate ~ m g l / (C w3) = 10 / 16 rad/s of the gyroscopic approximation.
    steps = np.diff(azimuth[k])
    assert np.all(steps * np.sign(mean_rate) > 0)
    assert 0.5 * 0.625 < abs(mean_rate) < 1.5 * 0.625


def test_rotor_euler_and_quaternion_variants_converge_together():
    # Both are second-order discretisations of the same motion far from the
    # singularity (theta stays near pi/2), so their difference scales as dt^2.
    d1 = np.abs(z_track("rotor-euler", 0.01) - z_track("rotor-quaternion", 0.01)).max()
    d2 = np.abs(z_track("rotor-euler", 0.005) - z_track("rotor-quaternion", 0.005)).max()
    assert d1 < 1e-2
    assert 3.0 < d1 / d2 < 5.0


def _energy_error(scene: str, dt: float) -> tuple[float, float, list]:
    sim = Simulation(load_scene(scene), dt=dt)
    e0 = sim.derived().energy
    worst = 0.0
    while sim.t < sim.scene.end_time - 1e-9:
        sim.step()
        worst = max(worst, abs(sim.derived().energy - e0))
    return worst, e0, sim.drain_events()


def test_gimbal_lock_pendulum_euler_warns_and_misbehaves_quaternion_does_not():
    err_e, e0, ev_e = _energy_error("gimbal-lock-pendulum", 0.01)
    assert [e.kind for e in ev_e][:1] == [EventKind.GIMBAL_LOCK] and ev_e[0].t == 0.0
    err_q1, _, ev_q = _energy_error("gimbal-lock-pendulum-quaternion", 0.01)
    err_q2, _, _ = _energy_error("gimbal-lock-pendulum-quaternion", 0.005)
    assert not any(e.kind is EventKind.GIMBAL_LOCK for e in ev_q)
    # Quaternions: Verlet's energy error ~ (w_max dt)^2 relative, w_max = sqrt(2 * 21 / 2)
    # (1 J kinetic + 20 J of potential at the bottom, B = 2): 2.1e-3; halving dt quarters it.
    assert err_q1 / e0 < 2.1e-3
    assert 3.0 < err_q1 / err_q2 < 5.0
    # Euler angles start at sin(theta) = 0: eq 5 is meaningless there and the energy is lost.
    assert err_e / e0 > 100 * err_q1 / e0
    assert err_e / e0 > 0.05


def test_gimbal_close_encounter_euler_warns_and_is_worse_than_quaternion():
    err_e, e0, ev_e = _energy_error("gimbal-lock-close", 0.01)
    err_q, _, ev_q = _energy_error("gimbal-lock-close-quaternion", 0.01)
    assert any(e.kind is EventKind.GIMBAL_LOCK for e in ev_e)
    assert not any(e.kind is EventKind.GIMBAL_LOCK for e in ev_q)
    # Both second order, but J ~ 1/sin(theta) (down to 0.31) inflates the Euler error constant.
    assert err_q / e0 < 2e-3
    assert err_e > 2.0 * err_q


def test_euler_mode_exactly_at_the_singularity_keeps_running_with_finite_numbers():
    sim = Simulation(load_scene("gimbal-lock-pendulum"))
    sim.step(100)
    assert np.all(np.isfinite(sim.y))
    assert math.isfinite(sim.derived().energy)
