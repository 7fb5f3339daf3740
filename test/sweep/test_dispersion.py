"""Seeded sampling: a flight's case depends on (master seed, index) alone."""
from __future__ import annotations

import math

import numpy as np

from lander_tools.sweep.dispersion import draw_case
from lander_tools.sweep.spec import parse_spec

SPEC = {
    "scene": "hover",
    "controller": "combined",
    "flights": 200,
    "seed": 11,
    "dispersions": {
        "initial_tilt": {"normal": {"mean": 0.0, "std": 0.1}},
        "initial_body_rate": {"normal": {"mean": 0.0, "std": 0.02}},
        "initial_altitude": {"uniform": {"min": -10.0, "max": 10.0}},
        "thrust_error": {"normal": {"mean": 0.0, "std": 0.03}},
        "thruster_failure": {"probability": 0.25, "time": {"uniform": {"min": 2.0, "max": 8.0}}},
    },
}


def test_case_is_a_function_of_seed_and_index_only():
    a = parse_spec(SPEC)
    b = parse_spec({**SPEC, "flights": 3})  # a different sweep size must not change flight 2
    assert draw_case(a, 2, 4) == draw_case(b, 2, 4)
    # Drawing other flights first (another order, another worker) changes nothing either.
    for i in range(10):
        draw_case(a, i, 4)
    assert draw_case(a, 2, 4) == draw_case(b, 2, 4)


def test_different_seeds_and_indices_give_different_cases():
    a = parse_spec(SPEC)
    c = parse_spec({**SPEC, "seed": 12})
    assert draw_case(a, 0, 4) != draw_case(a, 1, 4)
    assert draw_case(a, 0, 4) != draw_case(c, 0, 4)


def test_switching_one_dispersion_off_leaves_the_others_unchanged():
    a = parse_spec(SPEC)
    fewer = dict(SPEC["dispersions"])
    del fewer["initial_altitude"]
    b = parse_spec({**SPEC, "dispersions": fewer})
    ca, cb = draw_case(a, 5, 4), draw_case(b, 5, 4)
    assert cb.altitude_offset == 0.0
    assert ca.tilt == cb.tilt and ca.body_rate_B == cb.body_rate_B and ca.thrust_error == cb.thrust_error


def test_sample_statistics_match_the_specified_distributions():
    spec = parse_spec(SPEC)
    n = spec.flights
    cases = [draw_case(spec, i, 4) for i in range(n)]
    tilt = np.array([c.tilt for c in cases])
    alt = np.array([c.altitude_offset for c in cases])
    failed = np.array([c.failed_thruster >= 0 for c in cases])
    # Sample mean of n normal draws has std sigma/sqrt(n); 4 of those is a 1-in-15,000 miss.
    assert abs(tilt.mean()) < 4 * 0.1 / math.sqrt(n)
    # Sample std of n normal draws has relative std about 1/sqrt(2n) = 5 %; allow 4 of those.
    assert abs(tilt.std(ddof=1) / 0.1 - 1) < 4 / math.sqrt(2 * n)
    assert alt.min() >= -10.0 and alt.max() <= 10.0  # uniform support
    # Binomial(200, 0.25) count: std sqrt(n p (1-p)) ~ 6.1; allow 4 std.
    assert abs(failed.sum() - 0.25 * n) < 4 * math.sqrt(n * 0.25 * 0.75)
    for c in cases:
        if c.failed_thruster >= 0:
            assert 0 <= c.failed_thruster < 4 and 2.0 <= c.failure_time <= 8.0
        else:
            assert math.isnan(c.failure_time)


def test_no_dispersion_gives_the_nominal_case():
    spec = parse_spec({**SPEC, "dispersions": {}})
    c = draw_case(spec, 7, 4)
    assert c.tilt == 0.0 and c.body_rate_B == (0.0, 0.0, 0.0) and c.failed_thruster == -1
    assert c.thrust_error == (0.0, 0.0, 0.0, 0.0)
