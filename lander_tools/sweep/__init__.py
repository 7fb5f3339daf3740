"""Robustness sweeps: many seeded, dispersed flights flown core-only (no ROS), one summary.

``spec`` (YAML -> SweepSpec) -> ``dispersion`` (case of flight i from (seed, i)) -> ``flight``
(fly one case, metrics row) -> ``runner`` (local processes or Dask) -> ``summary``, ``output``,
``plots``. The command is ``lander sweep SPEC`` (:mod:`lander_tools.commands.sweep`).
"""
from lander_tools.sweep.spec import SweepSpec, SweepSpecError, load_spec, parse_spec

__all__ = ["SweepSpec", "SweepSpecError", "load_spec", "parse_spec"]
