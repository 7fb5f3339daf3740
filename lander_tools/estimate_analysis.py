"""The recorded estimate against the recorded truth: errors, 3-sigma bounds, NEES (no rclpy).

A flight flown with ``lander fly ... --estimate --record BAG`` holds the truth (``/lander/state``)
and the estimator node's ``/lander/estimate/odometry`` (``nav_msgs/Odometry`` with covariance), one
estimate per state with the state's stamp. ``lander analyse BAG`` pairs them by stamp
(:func:`errors`) and reports, per state component, the error, the filter's own 3-sigma bound, error
percentiles and the fraction inside 3 sigma, and the NEES of each block against its chi-square
bounds (:func:`report`; Bar-Shalom, Li and Kirubarajan, *Estimation with Applications to Tracking
and Navigation*, 2001, section 5.4, as :mod:`lander_autopilot.estimation.consistency`).

**Errors** (truth minus estimate, in the frames of the filter's error state, docs/estimation.md):

* position ``e_r = r_W - r_W_est`` [m], world axes (``mars``, planet-centred);
* velocity ``e_v = v_W - v_W_est`` [m/s], world axes; the Odometry carries the velocity and its
  covariance in the estimate's body axes (``base_link``, REP 105), so
  ``v_W_est = R^T v_B`` and ``P_v = R^T P_twist R`` with ``R = R(q_est)`` (world -> body);
* attitude ``e_th`` [rad], the rotation vector with ``q = q_est x dq(e_th)``, about the
  estimate's body axes (:func:`lander_autopilot.estimation.ekf.attitude_error`).

**Covariances from the Odometry.** The pose covariance is the filter's ``P`` over
``[dr, dth]`` (6 x 6, with the position-attitude cross terms); the twist covariance holds ``P_vv``
(rotated into body axes) alone. So the NEES of position, of velocity, of attitude (3 degrees of
freedom each) and of the pose (6) are exact marginals of the filter's; a joint position-velocity
NEES is not (the Odometry does not carry ``P_rv``), nor are the biases' (the truth has no bias
topic).

**NEES** ``eps_k = e_k^T P_k^-1 e_k`` of a block of ``n`` components at each of ``K`` paired states:
chi-square with ``n`` degrees of freedom for a consistent filter. Its time-average is reported with
two 95 % intervals (:func:`lander_autopilot.estimation.consistency.average_bounds`):

* ``[chi2(0.025; n K), chi2(0.975; n K)] / K``, exact for ``K`` independent samples;
* ``[chi2(0.025; n), chi2(0.975; n)]``, the single-time interval, which
  :func:`~lander_autopilot.estimation.consistency.anees` applies to a time-average: a flight's
  errors are correlated over many ticks (a filter's error moves on its own time constants, seconds
  to the whole flight for an unobservable state), so the ``K``-sample interval is too narrow for
  them and a time-average outside it alone does not show inconsistency; the single-time interval
  holds it with room. ``frac_inside`` is the fraction of samples whose NEES lies in the
  single-time interval (0.95 for a consistent filter).

**NIS** needs each update's innovation ``y`` and its covariance ``S``, which the estimator node
does not publish (its Odometry is the state after the tick's updates): :mod:`lander_tools.estimate_nis`
re-runs the filter over the bag's sensor messages, checks that it reproduces the recorded Odometry
bit for bit at every state, and only then reports NIS per sensor; otherwise NIS is n/a with the
reason.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from lander_autopilot.estimation.ekf import attitude_error
from lander_sim.physics.rotation import quat_to_matrix
from lander_tools.chi_square import ChiSquareSummary
from lander_tools.estimate_nis import NisReport, NisUnavailable
from lander_tools.estimate_nis import figure as nis_figure_of
from lander_tools.estimate_nis import from_bag as nis_from_bag
from lander_tools.metrics_fit import ESTIMATE_TOPIC, estimate_applies

ODOMETRY_TOPIC = ESTIMATE_TOPIC
#: The state blocks: name -> (component names, unit, figure unit and its scale from SI).
BLOCKS: dict[str, tuple[tuple[str, str, str], str, str, float]] = {
    "position": (("r_x", "r_y", "r_z"), "m", "m", 1.0),
    "velocity": (("v_x", "v_y", "v_z"), "m/s", "m/s", 1.0),
    "attitude": (("th_x", "th_y", "th_z"), "rad", "mrad", 1e3),
}
#: The frame each block's error is in (module docstring).
FRAMES = {
    "position": "world axes (mars, planet-centred)",
    "velocity": "world axes (mars, planet-centred)",
    "attitude": "rotation vector about the estimate's body axes, q = q_est x dq(th)",
}
#: Percentiles of |error| per component.
PERCENTILES = (50.0, 95.0, 99.0)
#: Why a bag has no estimate figures.
NO_ESTIMATE = f"the bag holds no {ODOMETRY_TOPIC} (record a flight flown with lander fly --estimate)"


@dataclass
class EstimateTrack:
    """The estimator's recorded Odometry, in the filter's frames: stamps ``t_ns`` [ns of sim time],
    ``r_W`` [m], ``v_W`` [m/s] (world axes), ``q`` (world -> body, core order ``s, x, y, z``),
    ``P_pose`` (N, 6, 6) over ``[dr (world), dth (body)]`` and ``P_v`` (N, 3, 3) in world axes."""

    t_ns: np.ndarray
    r_W: np.ndarray
    v_W: np.ndarray
    q: np.ndarray
    P_pose: np.ndarray
    P_v: np.ndarray

    @classmethod
    def from_series(cls, s: dict[str, np.ndarray]) -> EstimateTrack:
        """From :meth:`lander_tools.bagio.Bag.series` of the odometry topic. A reset starts the
        stamps again: the track is what follows the last reset (as :class:`~lander_tools.analysis.Flight`)."""
        t_ns = s["header.stamp.sec"].astype(np.int64) * 1_000_000_000 + s["header.stamp.nanosec"].astype(np.int64)
        back = np.flatnonzero(np.diff(t_ns) <= 0)
        k = int(back[-1] + 1) if len(back) else 0
        q = np.column_stack([s[f"pose.pose.orientation.{a}"] for a in "wxyz"])[k:]
        r = np.column_stack([s[f"pose.pose.position.{a}"] for a in "xyz"])[k:]
        v_B = np.column_stack([s[f"twist.twist.linear.{a}"] for a in "xyz"])[k:]
        pose = np.asarray(s["pose.covariance"], float).reshape(-1, 6, 6)[k:]
        twist = np.asarray(s["twist.covariance"], float).reshape(-1, 6, 6)[k:, 0:3, 0:3]
        v_W, P_v = body_to_world(q, v_B, twist)
        return cls(t_ns=t_ns[k:], r_W=r, v_W=v_W, q=q, P_pose=pose, P_v=P_v)


def body_to_world(q: np.ndarray, v_B: np.ndarray, P_B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``v_W = R^T v_B`` and ``P_W = R^T P_B R`` with ``R = R(q)`` (world -> body), per row."""
    R = np.array([quat_to_matrix(qi) for qi in q]).reshape(-1, 3, 3)
    Rt = np.transpose(R, (0, 2, 1))
    return np.einsum("nij,nj->ni", Rt, v_B), Rt @ P_B @ R


@dataclass
class EstimateErrors:
    """Truth minus estimate at the paired states (module docstring): times ``t`` [s], per block
    (``position``, ``velocity``, ``attitude``) the errors ``e[block]`` (K, 3) and covariances
    ``P[block]`` (K, 3, 3); ``P_pose`` (K, 6, 6) over ``[e_r, e_th]``. ``unpaired`` counts the
    truth states without an estimate of the same stamp."""

    t: np.ndarray
    e: dict[str, np.ndarray]
    P: dict[str, np.ndarray]
    P_pose: np.ndarray
    unpaired: int = 0

    def sigma(self, block: str) -> np.ndarray:
        """(K, 3) the filter's 1-sigma ``sqrt(P_ii)`` of each component."""
        return np.sqrt(np.clip(np.diagonal(self.P[block], axis1=1, axis2=2), 0.0, None))


def errors(t: np.ndarray, r_W: np.ndarray, v_W: np.ndarray, q: np.ndarray, track: EstimateTrack) -> EstimateErrors:
    """Pair the truth (times ``t`` [s], ``r_W``, ``v_W``, ``q`` per state) with ``track`` by stamp
    (to the nanosecond) and return the errors (module docstring)."""
    truth_ns = np.rint(np.asarray(t, float) * 1e9).astype(np.int64)
    idx = np.searchsorted(truth_ns, track.t_ns)
    ok = idx < len(truth_ns)
    ok[ok] = truth_ns[idx[ok]] == track.t_ns[ok]
    i_truth, i_est = idx[ok], np.flatnonzero(ok)
    e_th = np.array([attitude_error(track.q[j], q[i]) for i, j in zip(i_truth, i_est)]).reshape(-1, 3)
    pose = track.P_pose[i_est]
    return EstimateErrors(
        t=track.t_ns[i_est] * 1e-9,
        e={"position": r_W[i_truth] - track.r_W[i_est], "velocity": v_W[i_truth] - track.v_W[i_est],
           "attitude": e_th},
        P={"position": pose[:, 0:3, 0:3], "velocity": track.P_v[i_est], "attitude": pose[:, 3:6, 3:6]},
        P_pose=pose, unpaired=len(truth_ns) - len(i_truth))


def nees_series(e: np.ndarray, P: np.ndarray) -> np.ndarray:
    """``eps_k = e_k^T P_k^-1 e_k`` of (K, n) errors and (K, n, n) covariances; NaN where ``P_k``
    is singular."""
    e = np.asarray(e, float)
    out = np.full(len(e), np.nan)
    for k in range(len(e)):
        try:
            out[k] = float(e[k] @ np.linalg.solve(P[k], e[k]))
        except np.linalg.LinAlgError:
            pass
    return out


def nees_check(values: np.ndarray, dof: int, prob: float = 0.95) -> ChiSquareSummary:
    """The time-averaged NEES of one block (module docstring) from its ``values`` of ``dof``
    components, the non-finite ones (a singular ``P``) left out."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    if not len(v):
        raise ValueError("no finite NEES value to average")
    return ChiSquareSummary.of(v, dof, prob)


@dataclass(frozen=True)
class ComponentFigures:
    """One state component: percentiles of ``|e|`` (:data:`PERCENTILES`, SI units) and the
    fraction of samples with ``|e| <= 3 sigma``."""

    name: str
    unit: str
    percentiles: tuple[float, ...]
    inside_3sigma: float


def component_figures(e: np.ndarray, sigma: np.ndarray, names: tuple[str, ...], unit: str) -> list[ComponentFigures]:
    """:class:`ComponentFigures` of each column of (K, 3) errors ``e`` with 1-sigma ``sigma``."""
    a = np.abs(np.asarray(e, float))
    return [ComponentFigures(name=n, unit=unit, percentiles=tuple(float(np.percentile(a[:, j], p)) for p in PERCENTILES),
                             inside_3sigma=float(np.mean(a[:, j] <= 3.0 * sigma[:, j])))
            for j, n in enumerate(names)]


@dataclass
class EstimateReport:
    """What ``lander analyse`` says of one flight's estimate."""

    name: str
    states: int
    unpaired: int
    components: list[ComponentFigures]
    nees: dict[str, ChiSquareSummary]  #: position, velocity, attitude (3 dof), pose (6)
    errors: EstimateErrors
    #: NIS per sensor from the filter re-run (:mod:`lander_tools.estimate_nis`); None when not reported,
    #: and then ``nis_why`` says why.
    nis: NisReport | None = None
    nis_why: str = "not computed"

    def summary(self) -> dict[str, Any]:
        """The numbers, SI units, JSON-ready (``lander analyse --json``'s ``"estimate"``)."""
        return {
            "applies": True, "name": self.name, "states_paired": self.states, "states_unpaired": self.unpaired,
            "frames": dict(FRAMES),
            "components": {c.name: {"unit": c.unit, **{f"p{p:g}": v for p, v in zip(PERCENTILES, c.percentiles)},
                                    "inside_3sigma": c.inside_3sigma} for c in self.components},
            "nees": {k: {"mean": n.mean, "dof": n.dof, "samples": n.samples, "bounds": list(n.bounds),
                         "bounds_single_time": list(n.bounds_one), "frac_inside": n.frac_inside}
                     for k, n in self.nees.items()},
            "nis": None if self.nis is None else self.nis.summary(),
            "nis_why": "" if self.nis is not None else self.nis_why,
            "rerun": None if self.nis is None else self.nis.rerun_summary(),
        }

    def lines(self) -> list[str]:
        """The report as text for the terminal."""
        out = [f"estimate of {self.name}: {ODOMETRY_TOPIC} against /lander/state, {self.states} states paired "
               f"by stamp" + (f" ({self.unpaired} states without an estimate)" if self.unpaired else "")]
        out += [f"  {k}: {v}" for k, v in FRAMES.items()]
        head = (["component"] + [f"|e| p{p:g}" for p in PERCENTILES]
                + [f"inside 3 sigma (Gaussian {inside_3sigma_gaussian():.4f})"])
        rows = [[f"{c.name} [{c.unit}]"] + [f"{v:.4g}" for v in c.percentiles] + [f"{c.inside_3sigma:.4f}"]
                for c in self.components]
        head2 = ["NEES", "dof", "mean", "95 % (independent samples)", "95 % (single time)", "samples inside"]
        rows2 = [[k, str(n.dof), *n.cells()] for k, n in self.nees.items()]
        for h, rs in ((head, rows), (head2, rows2)):
            widths = [max(len(x) for x in col) for col in zip(h, *rs)]
            fmt = "  " + "  ".join(f"{{:<{w}}}" for w in widths)
            out += [fmt.format(*h).rstrip()] + [fmt.format(*r).rstrip() for r in rs]
        out += self.nis.lines() if self.nis is not None else [f"  NIS: n/a: {self.nis_why}"]
        return out


def report(name: str, t: np.ndarray, r_W: np.ndarray, v_W: np.ndarray, q: np.ndarray,
           track: EstimateTrack) -> EstimateReport | None:
    """The :class:`EstimateReport` of a flight's truth against ``track``; ``None`` when no state
    pairs with an estimate."""
    err = errors(t, r_W, v_W, q, track)
    if not len(err.t):
        return None
    comps: list[ComponentFigures] = []
    checks: dict[str, ChiSquareSummary] = {}
    for block, (names, unit, _, _) in BLOCKS.items():
        comps += component_figures(err.e[block], err.sigma(block), names, unit)
        checks[block] = nees_check(nees_series(err.e[block], err.P[block]), 3)
    e_pose = np.hstack([err.e["position"], err.e["attitude"]])
    checks["pose"] = nees_check(nees_series(e_pose, err.P_pose), 6)
    return EstimateReport(name=name, states=len(err.t), unpaired=err.unpaired, components=comps, nees=checks,
                          errors=err)


def from_bag(bag: Any, flight: Any) -> tuple[EstimateReport | None, str]:
    """The report of ``flight`` (:class:`~lander_tools.analysis.Flight` of ``bag``) and ``""``; or
    ``None`` and why the estimate's figures do not apply (:func:`lander_tools.metrics_fit.estimate_applies`:
    no estimate recorded; or no estimate with a state's stamp)."""
    if not estimate_applies(bag):
        return None, NO_ESTIMATE
    track = EstimateTrack.from_series(bag.series(ODOMETRY_TOPIC))
    rep = report(flight.name, flight.t, flight.r_W, flight.v_W, flight.q, track)
    if rep is None:
        return None, f"no message of {ODOMETRY_TOPIC} has the stamp of a state of the flight"
    try:
        rep.nis, rep.nis_why = nis_from_bag(bag), ""
    except NisUnavailable as exc:
        rep.nis_why = str(exc)
    return rep, ""


# --- figures -------------------------------------------------------------------------------------


def figure(rep: EstimateReport) -> Any:
    """Error and the filter's +-3 sigma of each component against time: one row per block
    (position, velocity, attitude), one column per axis."""
    from lander_tools import plotstyle as ps

    plt = ps.pyplot()
    fig, axes = plt.subplots(3, 3, sharex=True, figsize=(11, 7.5), layout="constrained", squeeze=False)
    err = rep.errors
    for i, (block, (names, _, unit, scale)) in enumerate(BLOCKS.items()):
        e, s = err.e[block] * scale, 3.0 * err.sigma(block) * scale
        for j in range(3):
            ax = axes[i, j]
            ax.fill_between(err.t, -s[:, j], s[:, j], color="0.85", lw=0, label="+-3 sigma (filter)")
            ax.plot(err.t, e[:, j], color=ps.colour(j), lw=0.8, label="truth - estimate")
            ax.set_ylabel(f"{names[j]} error [{unit}]")
            ax.set_xlabel("simulation time [s]")
            ax.xaxis.set_tick_params(labelbottom=True)
            ax.grid(True)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    ps.legend_outside(fig, handles, labels, where="outside lower center")
    fig.suptitle(f"{rep.name}: estimate errors; position and velocity in world axes, attitude about the "
                 "estimate's body axes", fontsize="medium")
    return fig


def nees_figure(rep: EstimateReport) -> Any:
    """NEES of each 3-component block against time, with the single-time 95 % interval (dashed)."""
    from lander_tools import plotstyle as ps

    plt = ps.pyplot()
    fig, axes = plt.subplots(3, 1, sharex=True, figsize=(8, 7.5), layout="constrained", squeeze=False)
    err = rep.errors
    for i, block in enumerate(BLOCKS):
        ax = axes[i, 0]
        eps = nees_series(err.e[block], err.P[block])
        lo, hi = rep.nees[block].bounds_one
        ax.semilogy(err.t, np.clip(eps, 1e-6, None), color=ps.colour(i), lw=0.8, label=f"NEES {block}")
        for b in (lo, hi):
            ax.axhline(b, color="0.3", ls="--", lw=1.0)
        ax.set_ylabel(f"NEES {block} (3 dof)")
        ax.set_xlabel("simulation time [s]")
        ax.xaxis.set_tick_params(labelbottom=True)
        ax.grid(True)
    fig.suptitle(f"{rep.name}: NEES with the chi-square(3) 95 % interval [{lo:.3g}, {hi:.3g}] (dashed)",
                 fontsize="medium")
    return fig


def write_figures(rep: EstimateReport, outdir: Path, prefix: str, suffix: str = "") -> list[Path]:
    """``<prefix>-estimate<suffix>.png`` (:func:`figure`), ``<prefix>-nees<suffix>.png``
    (:func:`nees_figure`) and, where NIS is reported, ``<prefix>-nis<suffix>.png``
    (:func:`lander_tools.estimate_nis.figure`) in ``outdir``; the paths written."""
    from lander_tools import plotstyle as ps

    out = [ps.save(figure(rep), outdir / f"{prefix}-estimate{suffix}.png"),
           ps.save(nees_figure(rep), outdir / f"{prefix}-nees{suffix}.png")]
    if rep.nis is not None and rep.nis.sensors:
        out.append(ps.save(nis_figure_of(rep.name, rep.nis), outdir / f"{prefix}-nis{suffix}.png"))
    return out


def inside_3sigma_gaussian(k: float = 3.0) -> float:
    """``P(|x| <= k sigma)`` of a Gaussian, ``erf(k / sqrt 2)`` (0.9973 at ``k = 3``)."""
    return math.erf(k / math.sqrt(2.0))
