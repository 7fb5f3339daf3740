"""Every plot the project draws, regenerated in the test run and read as a student would: both
axes of every axes labelled, no legend over the data, one colour per flight in every panel, a
trajectory's axes on one scale, and no matplotlib warning while drawing (docs/flying.md: what `lander analyse` draws).

The Figure objects are inspected, not pixels: ``lander analyse``'s kinds
(:func:`lander_tools.analysis_plots.figures`, the estimate's :mod:`lander_tools.estimate_analysis`), the rotor's z-axis track, the sweep plots and the
benchmarks' plots (their ``plot(data)`` functions, fed data in the shape of their JSON).
"""
from __future__ import annotations

import importlib.util
import math
import sys
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from lander_sim.physics.constants import MARS_RADIUS
from lander_sim.physics.rotation import quat_to_matrix
from lander_tools import plotstyle as ps
from lander_tools.analysis import Flight
from lander_tools.analysis_plots import PLOT_KINDS, figures, write_plots, ztrack_figure

BENCH = Path(__file__).resolve().parents[2] / "bench"


def _flight(name: str, t: np.ndarray, r_W: np.ndarray, q: np.ndarray | None = None,
            demand: list[tuple[float, float]] = ()) -> Flight:
    """A flight from its world-frame positions (and attitudes); the other series follow from them."""
    n = len(t)
    q = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1)) if q is None else q
    h = np.linalg.norm(r_W, axis=1) - MARS_RADIUS
    fuel = np.linspace(100.0, 90.0, n)
    return Flight(
        name=name, t=t, r_W=r_W, v_W=np.gradient(r_W, t, axis=0), q=q,
        euler=np.column_stack([0.01 * np.sin(t), np.pi / 2 + 0.02 * np.cos(t), 0.0 * t]),
        omega_B=np.column_stack([0.01 * np.cos(t), -0.02 * np.sin(t), 0.0 * t]),
        altitude=h, climb_rate=np.gradient(h, t), mass=100.0 + fuel, fuel=fuel,
        throttles=np.clip(0.5 + 0.1 * np.sin(np.outer(t, [1.0, 2.0, 3.0, 4.0])), 0.0, 1.0),
        phase=np.zeros(n, dtype=int), gimbal_lock=np.zeros(n, dtype=bool), sequence=np.arange(1, n + 1),
        demand_t=np.array([d[0] for d in demand]), demand=np.array([d[1] for d in demand]),
    )


def _hover(name: str, offset: float) -> Flight:
    """On the -y axis (as scene 'hover'), decaying onto 500 m; x and z stay exactly 0."""
    t = np.arange(0.0, 20.0, 0.1)
    r = MARS_RADIUS + 500.0 + offset * np.exp(-0.5 * t)
    return _flight(name, t, np.column_stack([0.0 * t, -r, 0.0 * t]), demand=[(0.0, 500.0), (10.0, 505.0)])


def _orbit() -> Flight:
    """A circular orbit in the x-y plane with +-0.04 m of z noise: what made the z axis autoscale."""
    t = np.arange(0.0, 600.0, 1.0)
    a = MARS_RADIUS + 200e3
    w = math.sqrt(4.2828e13 / a**3)
    return _flight("circular-orbit", t, np.column_stack([a * np.cos(w * t), a * np.sin(w * t), 0.04 * np.sin(7 * t)]))


def _rotor() -> Flight:
    """Body z precessing about the world z axis, tilted 30 deg: a cone on the unit sphere."""
    t = np.arange(0.0, 10.0, 0.01)
    half = math.radians(30.0) / 2
    q = np.column_stack([np.full_like(t, math.cos(half)), math.sin(half) * np.cos(t), math.sin(half) * np.sin(t), 0 * t])
    f = _flight("rotor-quaternion", t, np.tile([0.0, -MARS_RADIUS - 1.0, 0.0], (len(t), 1)), q=q)
    f.throttles = np.zeros((len(t), 0))  # a rotor has no thrusters: its throttle plot was the warning's source
    return f


def _drawn(build: Callable[[], Any]) -> Any:
    """Build a figure with every warning an error (matplotlib's "No artists with labels" included)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fig = build()
        fig.canvas.draw()  # lays out (constrained layout runs at draw time), may warn too
    return fig


def _read_as_a_student(fig: Any, flights: list[str] = ()) -> None:
    """Labels on every axis, legends off the data, and ``flights`` each in one colour of their own."""
    assert ps.unlabelled_axes(fig) == []
    axes = [a for a in fig.get_axes() if a.get_visible() and (a.axison or a.name == "3d") and a.get_label() != "<colorbar>"]
    legends = list(fig.legends) + [a.get_legend() for a in axes if a.get_legend() is not None]
    r = fig.canvas.get_renderer()
    for leg in legends:
        box = leg.get_window_extent(r)
        for a in axes:
            inter = box.intersection(box, a.get_window_extent(r))
            assert inter is None or inter.width * inter.height < 1.0, f"a legend covers {a.get_title() or a.get_ylabel()}"
    if len(flights) > 1:
        colours: dict[str, set[str]] = {}
        for a in axes:
            for ln in a.get_lines():
                if ln.get_gid() in flights:
                    colours.setdefault(ln.get_gid(), set()).add(ln.get_color())
        assert colours and set(colours) <= set(flights)  # (a rotor has no throttle lines)
        assert all(len(c) == 1 for c in colours.values()), colours
        assert len({c for cs in colours.values() for c in cs}) == len(colours)


def _close(fig: Any) -> None:
    ps.pyplot().close(fig)


@pytest.mark.parametrize("case", ["one flight", "two flights", "orbit", "rotor", "rotor and hover"])
def test_every_analyse_plot_kind_reads_well(case: str, tmp_path: Path) -> None:
    flights = {"one flight": lambda: [_hover("hover", 40.0)],
               "two flights": lambda: [_hover("p-only", 40.0), _hover("combined", -20.0)],
               "orbit": lambda: [_orbit()],
               "rotor": lambda: [_rotor()],
               "rotor and hover": lambda: [_rotor(), _hover("hover", 10.0)]}[case]()
    figs = {}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        figs = figures(flights)
    # A fixed pivot gets its z-axis track and no altitude (it flies over no surface).
    expected = {"rotor": set(PLOT_KINDS) - {"altitude"}, "rotor and hover": set(PLOT_KINDS)}
    assert set(figs) == expected.get(case, set(PLOT_KINDS) - {"ztrack"})
    names = [f.name for f in flights]
    for kind, fig in figs.items():
        _drawn(lambda fig=fig: fig)
        _read_as_a_student(fig, names if kind != "ztrack" else [])
        _close(fig)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        paths = write_plots(flights, tmp_path)
    assert sorted(p.name for p in paths) == sorted(f"flight-{k}.png" for k in figs)


def test_the_estimate_figures_read_well_and_draw_the_3_sigma_band() -> None:
    from lander_tools import estimate_analysis as ea

    n = 200
    t = np.arange(n) * 0.1
    rng = np.random.default_rng(1)
    q = np.tile([1.0, 0.0, 0.0, 0.0], (n, 1))
    r_W = np.column_stack([0.0 * t, -(MARS_RADIUS + 1000.0 - 3.0 * t), 0.0 * t])
    v_W = np.tile([0.0, 3.0, 0.0], (n, 1))
    sig = np.array([10.0, 10.0, 10.0, 1e-3, 1e-3, 1e-3])
    track = ea.EstimateTrack(t_ns=np.rint(t * 1e9).astype(np.int64), r_W=r_W + rng.normal(size=(n, 3)) * 10.0,
                             v_W=v_W + rng.normal(size=(n, 3)) * 0.5, q=q,
                             P_pose=np.tile(np.diag(sig**2), (n, 1, 1)), P_v=np.tile(np.eye(3) * 0.25, (n, 1, 1)))
    rep = ea.report("est", t, r_W, v_W, q, track)
    assert rep is not None
    for make in (ea.figure, ea.nees_figure):
        fig = _drawn(lambda make=make: make(rep))
        _read_as_a_student(fig)
        _close(fig)
    fig = ea.figure(rep)
    band = fig.get_axes()[0].collections[0].get_paths()[0].vertices[:, 1]  # r_x: +-3 sigma = +-30 m
    assert band.max() == pytest.approx(30.0) and band.min() == pytest.approx(-30.0)
    _close(fig)


def test_trajectory_has_one_scale_on_every_axis_so_orbit_noise_stays_flat() -> None:
    fig = _drawn(lambda: figures([_orbit()])["trajectory"])
    ax = fig.get_axes()[0]
    spans = [np.ptp(ax.get_xlim()), np.ptp(ax.get_ylim()), np.ptp(ax.get_zlim())]
    d = _orbit().r_W - _orbit().r_W[0]
    assert spans[2] == pytest.approx(spans[0]) and spans[1] == pytest.approx(spans[0])
    assert spans[2] >= np.ptp(d[:, 0])  # z shows the orbit's scale, not its 0.08 m of noise
    _close(fig)


def test_demand_is_drawn_dashed_in_its_flights_colour_over_the_whole_flight() -> None:
    f = _hover("hover", 40.0)
    fig = _drawn(lambda: figures([f])["altitude"])
    alt, dem = fig.axes[0].get_lines()
    assert dem.get_linestyle() == "--" and dem.get_color() == alt.get_color()
    assert list(dem.get_xdata()) == [0.0, 10.0, f.t[-1]] and list(dem.get_ydata()) == [500.0, 505.0, 505.0]
    _close(fig)


def test_rotor_z_track_is_the_unit_vector_of_reference_1_figure_1() -> None:
    f = _rotor()
    z = f.z_axis_track()
    np.testing.assert_allclose(z, [quat_to_matrix(q)[2] for q in f.q])
    fig = _drawn(lambda: ztrack_figure([(f.name, z, ps.colour(0))]))
    _read_as_a_student(fig)
    ax = fig.get_axes()[0]
    assert ax.get_xlim() == ax.get_ylim() == ax.get_zlim() == (-1.0, 1.0)
    _close(fig)


@pytest.fixture(scope="module")
def sweep_rows() -> tuple[Any, list[dict[str, Any]]]:
    from lander_tools.sweep.runner import run_local
    from lander_tools.sweep.spec import parse_spec

    spec = parse_spec({
        "name": "plots", "scene": "hover-canted", "controllers": ["combined", "lqr"], "flights": 4, "seed": 7,
        "end": {"duration": 3.0, "demand_step_time": 1.0, "hover_window": 1.0},
        "dispersions": {"initial_tilt": {"normal": {"mean": 0.0, "std": 0.05}},
                        "wind_mean": {"normal": {"mean": 0.0, "std": 2.0}}},
    }, "plots")
    return spec, run_local(spec, workers=1).rows


def test_every_sweep_plot_reads_well(sweep_rows) -> None:
    from lander_tools.sweep import plots

    spec, rows = sweep_rows
    hist = _drawn(lambda: plots.histograms_figure(rows, spec.metrics))
    _read_as_a_student(hist)
    assert all("[" in a.get_xlabel() for a in hist.get_axes() if a.axison)  # units on x
    sc = _drawn(lambda: plots.scatter_figure(rows, spec.metrics))
    _read_as_a_student(sc)
    assert {a.get_xlabel() for a in sc.get_axes()} == {"tilt [rad]", "wind_mean [m/s]"}
    worst = _drawn(lambda: plots.worst_trajectories_figure(spec, rows, 2))
    flown = {ln.get_gid() for a in worst.get_axes() for ln in a.get_lines()}
    assert len(flown) == 2
    _read_as_a_student(worst, sorted(flown))
    for fig in (hist, sc, worst):
        _close(fig)


def test_every_dispersed_parameter_and_metric_has_a_unit() -> None:
    from lander_tools.sweep.dispersion import PARAMETER_COLUMNS
    from lander_tools.sweep.plots import PARAMETER_UNITS, metric_label
    from lander_tools.sweep.spec import METRICS

    assert set(PARAMETER_UNITS) == set(PARAMETER_COLUMNS)
    assert all(not metric_label(m).endswith("[-]") for m in METRICS)


def _bench(name: str) -> Any:
    if str(BENCH) not in sys.path:
        sys.path.insert(0, str(BENCH))
    spec = importlib.util.spec_from_file_location(f"lander_bench_plot_{name}", BENCH / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def _bench_data(name: str, module: Any) -> dict[str, Any]:
    """Data in the shape each benchmark writes with --json (values are placeholders: only the
    drawing is under test here; the benchmarks' figures are tested in test/integrators)."""
    if name == "speed":
        return {"naive_steps_per_s": 1e4, "numpy_steps_per_s": 4e4, "kernel_steps_per_s": 2e6, "target_steps_per_s": 2e5}
    if name == "models":
        return {"one_by_one": [{"models": m, "steps_per_s": 1e5 / (k + 1)} for k, m in enumerate(["gravity", "+ drag"])]}
    if name == "integrators":
        return {"work_precision": [{"problem": p, "method": m, "evals": 10 * 2**k, "wall": 1e-3 * 2**k,
                                    "error": 10.0**-k, "unit": u}
                                   for p, u in (("kepler", "m"), ("top", "rad")) for m in ("verlet", "rk4") for k in range(3)]}
    return {"spin_sweep": [{"method": m, "spin": w, "dt": d, "energy_error": 1e-6 * w / d, "status": "ok"}
                           for m in module.METHODS for w in (0.5, 2.0) for d in (0.01, 0.1)]}


@pytest.mark.parametrize("name", ["speed", "models", "integrators", "extremes"])
def test_every_bench_plot_reads_well(name: str) -> None:
    module = _bench(name)
    fig = _drawn(lambda: module.plot(_bench_data(name, module)))
    _read_as_a_student(fig)
    _close(fig)
