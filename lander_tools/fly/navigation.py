"""What a law flown on the estimate (``lander fly --estimate``) is told of the navigation error.

A law that plans from its first state, the de-orbit laws (``deorbit``, ``deorbit-mpc``), has the
rows ``navigation_velocity_sigma`` and ``navigation_position_sigma``: the 1-sigma error per axis of
the state its burn is planned from, which widens the plan's test of a circular orbit to the apsides
split that error could make (docs/deorbit.md, "Burn planning"):

    tol = max(1 km, 2 a k sqrt((2 sigma_v / v + sigma_r / a)^2 + (sigma_v / v)^2)),   k = 3

On the estimate that state is the estimator's first estimate, at ``t = 0``: the truth plus an error
drawn from the filter's initial covariance ``P0`` (its ``initial_position_sigma``,
``initial_velocity_sigma``; lander_autopilot.estimation.flights.start_filter), then updated with the
readings at ``t = 0``. A Kalman update only shrinks the covariance (``P+ = P- - K S K^T``, Gelb 1974,
section 4.2), so the initial sigmas bound the first estimate's own: they are the sigmas the launcher
gives such a law, the values the comparison sweep sets (sweeps/compare-nav-deorbit.yaml). A value the
user gives (scene, ``--params``, ``--set``, scripted flight) stands. Plain Python: no ROS here.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from lander_autopilot.controllers.registry import parameter_table
from lander_autopilot.ros.estimator_config import SPECS as ESTIMATOR_SPECS

#: The law's row -> the estimator parameter whose value it takes (both 1 sigma per axis).
NAVIGATION_ROWS: dict[str, str] = {
    "navigation_position_sigma": "initial_position_sigma",  # m
    "navigation_velocity_sigma": "initial_velocity_sigma",  # m/s
}


def estimator_sigmas(estimator_params: Mapping[str, Any] | None = None) -> dict[str, float]:
    """The law's navigation rows with the estimator's initial sigmas: those of ``estimator_params``
    (the node's parameters as the flight sets them), else the node's defaults."""
    given = estimator_params or {}
    return {row: float(given.get(est, ESTIMATOR_SPECS[est].default)) for row, est in NAVIGATION_ROWS.items()}


def estimate_params(controller: str, params: Mapping[str, Any],
                    estimator_params: Mapping[str, Any] | None = None) -> dict[str, Any] | None:
    """``params`` of ``controller`` completed for a flight on the estimate: each navigation row the
    law has (its parameter table) and ``params`` does not set gets the estimator's initial sigma
    (:func:`estimator_sigmas`). None when nothing is added (a law without the rows, or both set):
    the flight then flies the parameters it was given, unchanged."""
    table = parameter_table(controller)
    if table is None:
        return None
    added = {k: v for k, v in estimator_sigmas(estimator_params).items() if k in table and k not in params}
    if not added:
        return None
    return {**dict(params), **added}
