"""Selecting integrators by name, and the errors for bad names, options and steps."""
from __future__ import annotations

import numpy as np
import pytest

from lander_sim.integrators import REGISTRY, IntegratorError, check_dt, make

from .problems import KeplerTop, state


def test_registry_has_every_method_docs_integrators_lists() -> None:
    assert set(REGISTRY) == {"verlet", "symplectic-euler", "rk4", "adaptive", "geometric", "dop853"}
    for name in REGISTRY:
        assert make(name).name == name


def test_unknown_name_lists_the_choices() -> None:
    with pytest.raises(ValueError, match=r"unknown integrator 'euler'; choose one of: adaptive, dop853, geometric, rk4, symplectic-euler, verlet"):
        make("euler")


def test_unknown_option_lists_the_options() -> None:
    with pytest.raises(IntegratorError, match=r"'rk4' has no option 'rtol'; its options are: renormalise"):
        make("rk4", rtol=1e-6)


@pytest.mark.parametrize("dt", [0.0, -0.1, float("nan"), "fast"])
@pytest.mark.parametrize("name", sorted(REGISTRY))
def test_non_positive_step_is_an_error_naming_dt(name: str, dt: object) -> None:
    dyn = KeplerTop((1.0, 2.0, 3.0), translation=False)
    y = state(np.zeros(3), np.zeros(3), [1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    before = y.copy()
    with pytest.raises(ValueError, match="time step dt must be a positive"):
        make(name).step(dyn, 0.0, y, dt)  # type: ignore[arg-type]  # a bad dt is the test
    assert np.array_equal(y, before)


def test_check_dt_returns_the_step() -> None:
    assert check_dt(0.01) == 0.01
