"""Guidance: reference trajectories and manoeuvres planned offline (plain numpy, scipy, cvxpy; no rclpy).

* :mod:`.deorbit`       the de-orbit burn (direction, size, timing, fuel) into a survivable entry
* :mod:`.fuel_optimal`  minimum-fuel powered descent by lossless convexification (Acikmese and
  Ploen 2007): the yardstick the flown descent laws are measured against.
"""
