"""The Dormand-Prince 5(4) tableau (Dormand & Prince, J. Comput. Appl. Math. 6 (1980) 19-26).

A leaf module: the numpy method (:mod:`lander_sim.integrators.adaptive`) and its compiled form
(:mod:`lander_sim.fast.rk_kernels`, which builds its arrays from these) both read it.
"""
from __future__ import annotations

#: Nodes c_i of the seven stages.
DP_C = (0.0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1.0, 1.0)
#: Stage weights: row i gives a_ij, j < i.
DP_A = (
    (),
    (1 / 5,),
    (3 / 40, 9 / 40),
    (44 / 45, -56 / 15, 32 / 9),
    (19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729),
    (9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656),
    (35 / 384, 0.0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84),
)
#: Difference between the 5th-order weights (= last row of DP_A) and the embedded 4th-order ones.
DP_E = (71 / 57600, 0.0, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40)
