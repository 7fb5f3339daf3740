"""The de-orbit laws ``deorbit`` and ``deorbit-mpc``: one mission (:mod:`.mission`) composed of parts.

* :mod:`.phases`: the phase machine (pure: phases, events, the transition table, their conditions);
* :mod:`.descent`: the scheduled descent law (braking limb in the chute's and the fitted air's drag);
* :mod:`.powered`: the powered-descent interface and its scheduled implementation; :mod:`.mpc` the MPC's;
* :mod:`.hover`: the hover capture; :mod:`.estimation`: thrust, density and drag learnt in flight;
* :mod:`.chute`: the chute decision; :mod:`.geometry`: the thrust axis's attitude and slope;
* :mod:`.params`: the two laws' parameter tables.
"""
from .descent import DescentToAltitude, FallDrag, still_air_limb_speed
from .geometry import AxisIntegral, axis_slope, thrust_axis_attitude
from .hover import HOVER_ATTITUDE_POLES, HoverCapture
from .mission import DeorbitController, DeorbitMpcController
from .mpc import MpcDescent, handover_problem
from .phases import DESCENT_PHASES, Event, Phase, PhaseLog, PhaseMachine
from .powered import PoweredDescent, ScheduledDescent

__all__ = [
    "DESCENT_PHASES", "HOVER_ATTITUDE_POLES", "AxisIntegral", "DeorbitController", "DeorbitMpcController",
    "DescentToAltitude", "Event", "FallDrag", "HoverCapture", "MpcDescent", "Phase", "PhaseLog", "PhaseMachine",
    "PoweredDescent", "ScheduledDescent", "axis_slope", "handover_problem", "still_air_limb_speed",
    "thrust_axis_attitude",
]
