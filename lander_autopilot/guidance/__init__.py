"""Guidance: reference trajectories and manoeuvres planned offline (plain numpy, scipy, cvxpy; no rclpy).

* :mod:`.deorbit`       the de-orbit burn (direction, size, timing, fuel) into a survivable entry
* :mod:`.fuel_optimal`  minimum-fuel powered descent by lossless convexification (Acikmese and
  Ploen 2007), with the open chute's drag by successive convexification: the yardstick the
  flown descent laws are measured against (docs/deorbit.md).
* :mod:`.descent_mpc`   model predictive control of the powered descent, tracking that optimum
  within the thrust, pointing and glide-slope limits (one cone-constrained QP a control period).
* :mod:`.conic_program` a cvxpy programme canonicalised once and solved by Clarabel directly each
  period (the MPC's solve inside its control period).
"""
