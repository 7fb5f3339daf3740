"""Shared sweep-test fixtures: one small, fully dispersed spec with short flights (fast)."""
from __future__ import annotations

import pytest

from lander_tools.sweep.spec import NONDETERMINISTIC_METRICS, parse_spec

#: Every dispersion on, so reproducibility covers every random stream (incl. gusts and failures).
SMALL = {
    "name": "small",
    "scene": "hover",
    "controllers": ["combined"],
    "flights": 6,
    "seed": 4242,
    "end": {"duration": 8.0, "demand_step_time": 3.0, "hover_window": 2.0},
    "dispersions": {
        "initial_tilt": {"normal": {"mean": 0.0, "std": 0.05}},
        "initial_body_rate": {"normal": {"mean": 0.0, "std": 0.01}},
        "initial_altitude": {"uniform": {"min": -20.0, "max": 20.0}},
        "initial_velocity": {"normal": {"mean": 0.0, "std": 0.5}},
        "wind_mean": {"normal": {"mean": 0.0, "std": 2.0}},
        "wind_gust": {"uniform": {"min": 0.0, "max": 1.0}},
        "demand_altitude_step": {"uniform": {"min": -50.0, "max": 50.0}},
        "mass_error": {"normal": {"mean": 0.0, "std": 0.02}},
        "inertia_error": {"normal": {"mean": 0.0, "std": 0.05}},
        "thrust_error": {"normal": {"mean": 0.0, "std": 0.02}},
        "thruster_failure": {"probability": 0.5, "time": {"uniform": {"min": 1.0, "max": 6.0}}},
    },
}


@pytest.fixture(scope="session")
def small_spec():
    return parse_spec(SMALL, "small")


def same_rows(a, b):
    """Bit-identical rows: ``repr`` of a float round-trips exactly, and NaN equals NaN here. The
    measured columns (``spec.NONDETERMINISTIC_METRICS``: compute time, MPC solve times) are left out:
    they are not a function of the flight."""
    def key(rows):
        return [{k: repr(v) for k, v in r.items() if k not in NONDETERMINISTIC_METRICS} for r in rows]

    return key(a) == key(b)
