"""Control design: linear models of the lander, controllability, pole placement and LQR.

Equation numbers refer to "The Extended Mars Lander, Exercise 2: Control" (the control reference;
docs/architecture.md, "References"). Modules:

* :mod:`.altitude`       eq 9-17: vertical model, hover throttle (eq 14)
* :mod:`.attitude`       eq 23, 25, 26, 28: attitude model from a :class:`Vehicle`
* :mod:`.numerical`      finite-difference linearisation of the nonlinear model (eq 3-4)
* :mod:`.controllability` eq 6: controllability matrix, rank, uncontrollable subspace
* :mod:`.gains`          pole placement (``place`` / ``place_varga``) and LQR
* :mod:`.report`         the design report of ``lander design SCENE``
"""
from __future__ import annotations


class DesignError(ValueError):
    """A design request that cannot be met (bad shapes, poles, weights); the message says which."""
