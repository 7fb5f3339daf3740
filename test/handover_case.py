"""The common handover case of the de-orbit tests: scenario 0's orbit flown by the scheduled law, the
state under the open chute some 7 s before its powered descent (t = 4639.9 s of `lander fly deorbit`),
rounded; straight down, no wind, thrust axis up (docs/deorbit.md)."""
from __future__ import annotations

import dataclasses

import numpy as np

HEIGHT, CLIMB, FUEL = 852.0, -36.8, 67.39  # [m], [m/s], [kg]


def handover_sim():
    """``(scene, simulation)`` of scene ``deorbit`` started in the handover case, chute deployed."""
    from lander_autopilot.controllers.deorbit import thrust_axis_attitude
    from lander_sim.physics import constants as c
    from lander_sim.scenes import load_scene
    from lander_sim.simulation import Simulation

    sc = load_scene("deorbit")
    y = sc.initial_state.copy()
    y[0:3] = (c.MARS_RADIUS + HEIGHT, 0.0, 0.0)
    y[3:6] = (CLIMB, 0.0, 0.0)
    y[6:10] = thrust_axis_attitude(y[6:10], np.array([1.0, 0.0, 0.0]))  # thrust axis up
    y[10:13] = 0.0
    y[13] = FUEL
    sc = dataclasses.replace(sc, initial_state=y)
    sim = Simulation(sc)
    sim.deploy_parachute()
    return sc, sim
