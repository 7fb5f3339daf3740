"""A model is owned by its module (docs/physics.md, "Adding a model"): adding a force model is one module and one
row of the models table (lander_sim/physics/models/table.py), nothing in the loader or the
simulation. Shown here with a module written in this file (a linear spring to a world-frame anchor)
and one row put into the table for the test.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest

from lander_sim.physics.models.base import BuildContext, Built, EvalContext, ModelEntry
from lander_sim.physics.models.table import MODELS
from lander_sim.scenes import SceneError, parse_scene
from lander_sim.simulation import Simulation
from lander_sim.yaml_file import Reader

# --- the new model's module: force, config, parse, build, entry ------------------------------


@dataclass
class Spring:
    """``F_W = -k (r_W - anchor_W)`` on the centre of mass [N]: a harmonic oscillator."""

    k: float
    anchor_W: np.ndarray
    name: str = "spring"
    calls: int = 0

    def add(self, ctx: EvalContext, force_W: np.ndarray, force_B: np.ndarray, torque_B: np.ndarray) -> None:
        self.calls += 1
        force_W -= self.k * (ctx.y[0:3] - self.anchor_W)


@dataclass(frozen=True)
class SpringConfig:
    k: float  # [N/m]
    anchor_W: tuple[float, float, float]  # [m], world frame


def parse(rd: Reader, node: object, path: str) -> SpringConfig:
    s = rd.mapping(node, path, {"k", "anchor_W"}, ("k",))
    return SpringConfig(rd.number(s["k"], f"{path}.k", 0.0, strict_lo=True),
                        rd.vector3(s.get("anchor_W", [0.0, 0.0, 0.0]), f"{path}.anchor_W"))


def build(cfg: SpringConfig, ctx: BuildContext) -> Built:
    return Built(forces=(Spring(cfg.k, np.array(cfg.anchor_W, dtype=float)),))


ENTRY = ModelEntry("spring", parse, build)

# --- the tests -----------------------------------------------------------------------------------

MASS = 100.0  # kg: a vehicle of dry mass only
K = 4.0  # N/m: omega = 0.2 rad/s, period 31.4 s
AMPLITUDE = 10.0  # m


@pytest.fixture
def spring_row(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(MODELS, "spring", ENTRY)  # the one table row


def _scene(models: dict[str, Any], dt: float = 0.01) -> Any:
    return parse_scene({
        "name": "spring", "vehicle": {"dry_mass": MASS, "inertia": [1.0, 1.0, 1.0]}, "dt": dt,
        "integrator": "verlet", "initial": {"position_W": [AMPLITUDE, 0.0, 0.0]}, "models": models,
    }, "spring.yaml")


def test_a_new_model_is_one_module_and_one_table_row(spring_row: None) -> None:
    """The scene switches the spring on, the loader parses its section with its module's parser,
    the simulation builds it: the lander oscillates as x = A cos(omega t), omega = sqrt(k/m).

    Tolerance from theory: velocity Verlet on a harmonic oscillator keeps the amplitude (it is
    symplectic) and lags the phase by omega^3 dt^2 / 24 per unit time, so after T the position is
    off by at most A omega^3 dt^2 T / 24 (6.7e-6 m here); twice that is the bound."""
    dt, T = 0.01, 20.0
    sim = Simulation(_scene({"spring": {"k": K}}, dt))
    assert [m.name for m in sim.dynamics.models] == ["spring"]
    sim.step(round(T / dt))
    omega = math.sqrt(K / MASS)
    bound = 2.0 * AMPLITUDE * omega**3 * dt**2 * T / 24.0
    assert abs(sim.y[0] - AMPLITUDE * math.cos(omega * T)) <= bound


def test_the_new_models_errors_name_its_keys_in_the_loaders_style(spring_row: None) -> None:
    with pytest.raises(SceneError, match=r"spring.yaml: models.spring.k: expected a number > 0.0, got -1.0"):
        _scene({"spring": {"k": -1.0}})
    with pytest.raises(SceneError, match=r"spring.yaml: models.spring.stiffness: unknown key; allowed keys: anchor_W, k"):
        _scene({"spring": {"k": 1.0, "stiffness": 2.0}})


def test_without_its_row_the_model_is_an_unknown_key_and_the_error_lists_the_table() -> None:
    with pytest.raises(SceneError, match=r"models.spring: unknown key; allowed keys: " + ", ".join(sorted(MODELS))):
        _scene({"spring": {"k": K}})


def test_the_fast_path_declines_a_model_it_does_not_know(spring_row: None) -> None:
    from lander_sim.fast import unsupported_reason

    reason = unsupported_reason(_scene({"spring": {"k": K}}))
    assert reason is not None and reason.startswith("model(s) spring (fast path:")


def test_the_tables_order_is_the_order_forces_are_summed() -> None:
    """Part of a flight's bit-for-bit identity: floating-point sums depend on their order."""
    assert list(MODELS) == ["gravity", "atmosphere", "drag", "parachute", "thrusters", "constant_force", "ground"]
