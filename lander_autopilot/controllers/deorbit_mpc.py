"""``deorbit-mpc``'s import path: the law and its handover problem live in :mod:`.deorbit`
(:class:`.deorbit.DeorbitMpcController`, :func:`.deorbit.mpc.handover_problem`)."""
from .deorbit.mission import DeorbitMpcController
from .deorbit.mpc import handover_problem

__all__ = ["DeorbitMpcController", "handover_problem"]
