"""The autopilot node's ROS shell helpers (see :mod:`lander_autopilot.node`).

* :mod:`.config`: the node's parameters (names, defaults, descriptions, validation) and the
  choice of controller, parameters and demand from a scene's ``autopilot`` section.
* :mod:`.convert`: ``LanderState`` -> :class:`~lander_sim.physics.state.StateView`,
  :class:`~lander_autopilot.controllers.ControlOutput` -> ``ThrottleCommand``, status and events.
* :mod:`.slot`: the active controller and demand, swapped whole between two control steps.

No control law and no physics here: the laws are :mod:`lander_autopilot.controllers`.
"""
