"""Wind: a steady mean plus seeded, deterministic turbulence (world frame, m/s).

The gusts are a first-order Gauss-Markov process per world axis (Ornstein-Uhlenbeck)::

    dg = -g / tau dt + sigma sqrt(2 / tau) dW

held constant over each simulation step and advanced by the **exact** discretisation over that
step, ``g_{k+1} = a g_k + sigma sqrt(1 - a^2) w_k`` with ``a = exp(-dt / tau)`` and ``w_k``
independent standard normal triples. Exact means its statistics (stationary std ``sigma``,
autocorrelation ``exp(-|lag| / tau)``) do not depend on the step size, and the process starts in
its stationary distribution (``g_0 ~ N(0, sigma^2)`` per axis), so there is no warm-up transient.

Determinism: one ``numpy.random.Generator`` (PCG64) seeded from ``seed`` alone, drawn three
normals per step in a fixed order, so a flight re-flown from the same seed sees bit-identical
gusts whatever the caller's stepping pattern (``step(10)`` or ten ``step(1)``), engine or path
(compiled kernel or numpy). The wind a model sees is ``mean_W + g``; :meth:`GustProcess.advance`
writes it in place, allocating nothing.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np


class WindError(ValueError):
    """A bad wind or gust setting; the message names the field and the value."""


@dataclass(frozen=True)
class GustConfig:
    """Turbulence settings (scene key ``wind.gust``).

    Attributes
    ----------
    sigma : float
        Stationary standard deviation of each world-axis gust component [m/s], >= 0.
    tau : float
        Correlation time [s], > 0: the autocorrelation at lag ``s`` is ``exp(-s / tau)``.
    seed : int
        Seed of the random stream, an integer in [0, 2**63) (fits a ROS int64 parameter).
    """

    sigma: float
    tau: float
    seed: int = 0

    def __post_init__(self) -> None:
        if not (isinstance(self.sigma, (int, float)) and math.isfinite(self.sigma) and self.sigma >= 0.0):
            raise WindError(f"gust sigma must be a finite number of m/s >= 0, got {self.sigma!r}")
        if not (isinstance(self.tau, (int, float)) and math.isfinite(self.tau) and self.tau > 0.0):
            raise WindError(f"gust tau must be a finite number of seconds > 0, got {self.tau!r}")
        check_seed(self.seed)


def check_seed(seed: Any) -> int:
    """``seed`` as an int in [0, 2**63); :class:`WindError` naming the value otherwise."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= int(seed) < 2**63:
        raise WindError(f"seed must be an integer in [0, 2**63), got {seed!r}")
    return int(seed)


class GustProcess:
    """Seeded Gauss-Markov gusts on a fixed step ``dt`` [s] (see the module docstring).

    Attributes
    ----------
    gust_W : ndarray (3,)
        The current gust, world frame [m/s] (read only for callers).
    """

    def __init__(self, config: GustConfig, dt: float) -> None:
        if not (math.isfinite(dt) and dt > 0.0):
            raise WindError(f"gust step dt must be a finite number of seconds > 0, got {dt!r}")
        self.config = config
        self.a = math.exp(-dt / config.tau)
        # sqrt(1 - a^2) via expm1 keeps precision when dt << tau (a close to 1).
        self.b = config.sigma * math.sqrt(-math.expm1(-2.0 * dt / config.tau))
        self.gust_W = np.zeros(3)
        self._w = np.zeros(3)
        self.reset(config.seed)

    def reset(self, seed: int | None = None) -> None:
        """Restart from ``seed`` (None: the seed in force) with a draw from the stationary distribution."""
        if seed is not None:
            self.seed = check_seed(seed)
        elif not hasattr(self, "seed"):
            self.seed = self.config.seed
        self.rng = np.random.default_rng(self.seed)
        self.rng.standard_normal(out=self.gust_W)
        self.gust_W *= self.config.sigma

    def advance(self) -> None:
        """One step of the exact discretisation: ``g <- a g + sigma sqrt(1 - a^2) w``."""
        w, g = self._w, self.gust_W
        self.rng.standard_normal(out=w)
        g *= self.a
        w *= self.b
        g += w

    # --- determinism ---------------------------------------------------------------------------

    def get_state(self) -> tuple[dict[str, Any], np.ndarray, int]:
        """Everything that determines the future (generator state, current gust, seed)."""
        return dict(self.rng.bit_generator.state), self.gust_W.copy(), self.seed

    def set_state(self, state: tuple[dict[str, Any], np.ndarray, int]) -> None:
        bits, gust, seed = state
        self.seed = seed
        self.rng.bit_generator.state = bits
        self.gust_W[:] = gust


def sample_gusts(config: GustConfig, dt: float, n: int) -> np.ndarray:
    """``n`` consecutive gust values (rows, world frame, m/s) from a fresh process: the first is
    the initial draw, each next one advanced by ``dt``. For tests and plots."""
    p = GustProcess(config, dt)
    out = np.empty((n, 3))
    for k in range(n):
        out[k] = p.gust_W
        p.advance()
    return out
