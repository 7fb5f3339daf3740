"""The ROS side of the simulator: parameters, conversions, pacing, markers and diagnostics for lander_sim.node."""
