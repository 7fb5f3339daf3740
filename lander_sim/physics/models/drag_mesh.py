"""Drag over a mesh of surface elements (the extended program's model), with aerodynamic torque.

For each element ``i`` (centre ``p_i``, outward unit normal ``n_i``, area ``a_i``, body
frame) the local air velocity relative to the surface is

    ``W_i = R (wind_W - v_W) - omega_B x p_i``   (body frame).

Only elements facing the flow (``W_i . n_i < 0``) feel anything:

* bluff-body (Newtonian) pressure ``rho (W_i . n_i)^2`` pushing along ``-n_i``;
* skin friction ``1/2 rho Cf a_i |W_t| W_t`` along the tangential flow ``W_t = W_i - (W_i . n_i) n_i``.

The body torque is ``sum p_i x F_i``. Newtonian pressure on a sphere of radius ``r``
integrates to ``1/2 rho |W|^2 (pi r^2)``, i.e. Cd = 1 on area ``pi r^2``: with the
default sphere of radius ``L`` the mesh model tends to :class:`SphereDrag` as the
mesh is refined (a test checks this), and it adds torque once the shape's centre
is offset from the centre of mass or the body spins.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lander_sim.physics.models.base import EvalContext


def sphere_mesh(radius: float, centre_B: np.ndarray, n_lat: int, n_lon: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Panels of a UV sphere: ``(centres (n,3), outward normals (n,3), areas (n,))``, body frame.

    Areas are exact spherical-zone areas (``r^2 dlon (cos lat0 - cos lat1)``) so the
    total is exactly ``4 pi r^2``; centres sit at the middle of each panel.
    """
    th = np.linspace(0.0, math.pi, n_lat + 1)  # polar angle from +z
    ph = np.linspace(0.0, 2.0 * math.pi, n_lon + 1)
    thc = 0.5 * (th[:-1] + th[1:])
    phc = 0.5 * (ph[:-1] + ph[1:])
    T, P = np.meshgrid(thc, phc, indexing="ij")
    normals = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], axis=-1).reshape(-1, 3)
    zone = (np.cos(th[:-1]) - np.cos(th[1:]))[:, None] * np.full((1, n_lon), 2.0 * math.pi / n_lon)
    areas = (radius * radius * zone).reshape(-1)
    centres = np.asarray(centre_B, dtype=float) + radius * normals
    return centres, normals, areas


@dataclass
class MeshDrag:
    """Surface-element drag and torque (see the module docstring).

    Attributes
    ----------
    centres_B, normals_B : ndarray (n, 3)
        Element centres relative to the centre of mass [m] and outward unit normals, body frame.
    areas : ndarray (n,)
        Element areas [m^2].
    skin_friction : float
        Skin-friction coefficient ``Cf``.
    """

    centres_B: np.ndarray
    normals_B: np.ndarray
    areas: np.ndarray
    skin_friction: float = 0.005
    name: str = "drag"
    calls: int = 0

    def forces_B(self, rho: float, W_B: np.ndarray, omega_B: np.ndarray) -> np.ndarray:
        """Per-element force ``(n, 3)`` [N], body frame, for relative air velocity ``W_B`` at the centre of mass."""
        # omega x p_i for all elements; np.cross is slow on (n, 3) (axis juggling).
        P = self.centres_B
        w0, w1, w2 = float(omega_B[0]), float(omega_B[1]), float(omega_B[2])
        W = np.empty_like(P)
        W[:, 0] = W_B[0] - (w1 * P[:, 2] - w2 * P[:, 1])
        W[:, 1] = W_B[1] - (w2 * P[:, 0] - w0 * P[:, 2])
        W[:, 2] = W_B[2] - (w0 * P[:, 1] - w1 * P[:, 0])
        wn = np.einsum("ij,ij->i", W, self.normals_B)
        facing = wn < 0.0
        Wt = W - wn[:, None] * self.normals_B
        wt = np.sqrt(np.einsum("ij,ij->i", Wt, Wt))
        pressure = -(rho * wn * wn * self.areas)[:, None] * self.normals_B
        friction = (0.5 * rho * self.skin_friction * self.areas * wt)[:, None] * Wt
        return np.where(facing[:, None], pressure + friction, 0.0)

    def add(self, ctx: EvalContext, force_W: np.ndarray, force_B: np.ndarray, torque_B: np.ndarray) -> None:
        self.calls += 1
        rho = ctx.rho
        if rho == 0.0:
            return
        y = ctx.y
        W_B = ctx.R @ (ctx.inputs.wind_W - y[3:6])
        F = self.forces_B(rho, W_B, y[10:13])
        force_B += F.sum(axis=0)
        P = self.centres_B
        torque_B[0] += float(P[:, 1] @ F[:, 2] - P[:, 2] @ F[:, 1])
        torque_B[1] += float(P[:, 2] @ F[:, 0] - P[:, 0] @ F[:, 2])
        torque_B[2] += float(P[:, 0] @ F[:, 1] - P[:, 1] @ F[:, 0])
