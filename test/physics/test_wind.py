"""The gust process: Gauss-Markov statistics, exact discretisation, seeded bit-identical replays."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from lander_sim.errors import InputError
from lander_sim.physics.wind import GustConfig, GustProcess, WindError, sample_gusts
from lander_sim.scenes import SceneError, load_scene, parse_scene
from lander_sim.simulation import Simulation

SIGMA, TAU = 0.8, 2.0


@pytest.mark.parametrize("dt", [0.02, 0.1, 0.5])
def test_std_and_lag_one_autocorrelation_match_sigma_and_exp(dt):
    n = 100_000
    g = sample_gusts(GustConfig(SIGMA, TAU, seed=12345), dt, n)
    a = math.exp(-dt / TAU)
    # Sample variance of an AR(1) series with coefficient a: relative std sqrt(2/n (1+a^2)/(1-a^2))
    # (Bartlett); the std's relative std is half that, and pooling 3 independent axes divides by
    # sqrt(3). 5 of those is a 1-in-1.7-million miss for a correct process.
    rel = 0.5 * math.sqrt(2.0 / n * (1 + a * a) / (1 - a * a)) / math.sqrt(3)
    assert np.sqrt(np.mean(g.var(axis=0))) == pytest.approx(SIGMA, rel=5 * rel)
    # Lag-one autocorrelation estimator of an AR(1): std sqrt((1 - a^2) / n), pooled over 3 axes.
    rho = np.mean([np.corrcoef(g[:-1, i], g[1:, i])[0, 1] for i in range(3)])
    assert rho == pytest.approx(a, abs=5 * math.sqrt((1 - a * a) / n) / math.sqrt(3))
    # Mean zero: the std of a mean of an AR(1) is sigma sqrt((1+a)/((1-a) n)); pooled, 5 of those.
    assert abs(g.mean()) < 5 * SIGMA * math.sqrt((1 + a) / ((1 - a) * n)) / math.sqrt(3)


def test_autocorrelation_at_one_correlation_time_is_exp_minus_one_whatever_the_step():
    # The discretisation is exact, so at lag tau the correlation is e^-1 for a coarse and a fine
    # step alike (an Euler discretisation would give (1 - dt/tau)^(tau/dt), visibly off at dt = 0.5).
    for dt in (0.05, 0.5):
        n, lag = 200_000, int(round(TAU / dt))
        g = sample_gusts(GustConfig(SIGMA, TAU, seed=7), dt, n)
        rho = np.mean([np.corrcoef(g[:-lag, i], g[lag:, i])[0, 1] for i in range(3)])
        # Std of the lag-L estimate for AR(1) (Bartlett): sqrt((1 + a^2)(1 - a^(2L))/(1 - a^2) - 2 L a^(2L)) / sqrt(n);
        # with a^L = e^-1 this is at most sqrt(tau/dt) / sqrt(n) times a constant ~1.3. Pooled 3 axes, 5 std.
        a = math.exp(-dt / TAU)
        var = ((1 + a * a) * (1 - a ** (2 * lag)) / (1 - a * a) - 2 * lag * a ** (2 * lag)) / n
        assert rho == pytest.approx(math.exp(-1.0), abs=5 * math.sqrt(var / 3)), dt


def test_same_seed_replays_bit_for_bit_and_other_seeds_differ():
    cfg = GustConfig(SIGMA, TAU, seed=99)
    a, b = sample_gusts(cfg, 0.1, 500), sample_gusts(cfg, 0.1, 500)
    assert np.array_equal(a, b)
    c = sample_gusts(dataclasses.replace(cfg, seed=100), 0.1, 500)
    assert not np.any(a == c)  # independent streams: no value in common
    p = GustProcess(cfg, 0.1)
    for _ in range(10):
        p.advance()
    state = p.get_state()
    later = [p.gust_W.copy() for _ in range(5) if p.advance() is None]
    p.set_state(state)
    again = [p.gust_W.copy() for _ in range(5) if p.advance() is None]
    assert np.array_equal(np.array(later), np.array(again))


def test_zero_sigma_is_exactly_calm_and_bad_settings_name_the_field():
    assert not np.any(sample_gusts(GustConfig(0.0, TAU), 0.1, 50))
    with pytest.raises(WindError, match="sigma"):
        GustConfig(-1.0, TAU)
    with pytest.raises(WindError, match="tau"):
        GustConfig(1.0, 0.0)
    with pytest.raises(WindError, match="seed"):
        GustConfig(1.0, 1.0, seed=-3)


# --- in the simulation ---------------------------------------------------------------------------


def gusty(seed: int = 5, sigma: float = 1.5, **extra) -> object:
    """Scenario 7 (hover) with a mean wind and gusts, throttles held at a hover-ish 0.5."""
    base = load_scene("hover")
    return dataclasses.replace(base, wind_W=(2.0, 0.0, -1.0), gust=GustConfig(sigma, 1.0, seed), **extra)


def fly(sim: Simulation, chunks: list[int]) -> tuple[np.ndarray, np.ndarray]:
    winds = []
    sim.set_throttles([0.5] * 4)
    for n in chunks:
        winds.append(sim.inputs.wind_W.copy())
        sim.step(n)
    return sim.y.copy(), np.array(winds)


def test_simulation_gusts_are_bit_identical_per_seed_and_independent_of_step_grouping():
    y1, _ = fly(Simulation(gusty()), [1] * 60)
    y2, _ = fly(Simulation(gusty()), [10] * 6)  # the same 60 steps in 6 calls
    assert np.array_equal(y1, y2)
    y3, _ = fly(Simulation(gusty(seed=6)), [1] * 60)
    assert not np.array_equal(y1, y3)  # another seed, other gusts, another flight


def test_simulation_gusts_are_the_same_on_the_compiled_and_numpy_paths():
    fast, slow = Simulation(gusty()), Simulation(gusty(), use_fast_path=False)
    _, w_fast = fly(fast, [1] * 40)
    _, w_slow = fly(slow, [1] * 40)
    # The wind does not depend on the state, so it is bit-identical; the states agree to the
    # kernel's documented ~1e-12 relative (different operation order, same equations).
    assert np.array_equal(w_fast, w_slow)
    assert np.allclose(fast.y, slow.y, rtol=1e-10, atol=1e-9)


def test_wind_is_mean_plus_gust_and_set_wind_replaces_the_mean():
    sim = Simulation(gusty())
    g0 = sim.gusts.gust_W.copy()
    assert np.array_equal(sim.inputs.wind_W, np.array([2.0, 0.0, -1.0]) + g0)
    sim.set_wind([0.0, 20.0, 0.0])
    assert np.array_equal(sim.inputs.wind_W, np.array([0.0, 20.0, 0.0]) + g0)
    sim.step(3)
    assert np.array_equal(sim.inputs.wind_W - sim.gusts.gust_W, np.array([0.0, 20.0, 0.0]))
    sim.reset()  # the mean goes back to the scene's
    assert np.array_equal(sim.mean_wind_W, [2.0, 0.0, -1.0])


def test_reset_replays_and_reset_with_a_seed_reseeds():
    sim = Simulation(gusty(seed=5))
    y_a, _ = fly(sim, [1] * 30)
    sim.reset()
    y_b, _ = fly(sim, [1] * 30)
    assert np.array_equal(y_a, y_b)  # plain reset: same seed, same flight
    sim.reset(seed=6)
    y_c, _ = fly(sim, [1] * 30)
    y_6, _ = fly(Simulation(gusty(seed=6)), [1] * 30)
    assert np.array_equal(y_c, y_6)  # reseeded exactly as a scene with that seed
    sim.reset()
    assert np.array_equal(fly(sim, [1] * 30)[0], y_6)  # the given seed stays in force
    with pytest.raises(InputError, match="seed"):
        sim.reset(seed=-1)


def test_snapshot_restore_continues_the_gusts_bit_exactly():
    sim = Simulation(gusty())
    fly(sim, [1] * 10)
    snap = sim.snapshot()
    y_a, w_a = fly(sim, [1] * 20)
    sim.restore(snap)
    y_b, w_b = fly(sim, [1] * 20)
    assert np.array_equal(y_a, y_b) and np.array_equal(w_a, w_b)


def test_scene_wind_keys_are_validated_naming_the_key():
    base = {"vehicle": {"preset": "lander"}, "initial": {"position_W": [0, -3396200.0, 0]}, "dt": 0.1,
            "models": {"gravity": {"kind": "inverse-square"}}}
    s = parse_scene({**base, "wind": {"mean_W": [1, 2, 3], "gust": {"sigma": 0.5, "tau": 2.0, "seed": 4}}}, "w.yaml")
    assert s.wind_W == (1.0, 2.0, 3.0) and s.gust == GustConfig(0.5, 2.0, 4)
    assert parse_scene({**base, "wind_W": [1, 0, 0]}, "w.yaml").wind_W == (1.0, 0.0, 0.0)  # the older key
    bad = {
        "wind.gust.sigma": {"wind": {"gust": {"sigma": -0.5, "tau": 2.0}}},
        "wind.gust.tau": {"wind": {"gust": {"sigma": 0.5, "tau": 0}}},
        "wind.gust.seed": {"wind": {"gust": {"sigma": 0.5, "tau": 1.0, "seed": 1.5}}},
        "wind.gust.gusty": {"wind": {"gust": {"sigma": 0.5, "tau": 1.0, "gusty": 1}}},
        "wind.mean_W": {"wind": {"mean_W": [1, 2, 3]}, "wind_W": [0, 0, 0]},
    }
    for key, extra in bad.items():
        with pytest.raises(SceneError, match=rf"w\.yaml: {key.replace('.', chr(92) + '.')}"):
            parse_scene({**base, **extra}, "w.yaml")
