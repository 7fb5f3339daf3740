"""Guidance: reference trajectories planned offline (plain numpy, scipy and cvxpy; no rclpy).

* :mod:`.fuel_optimal`  minimum-fuel powered descent by lossless convexification (Acikmese and
  Ploen 2007): the yardstick the flown descent laws are measured against.
"""
