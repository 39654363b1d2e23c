"""The axis-aligned manufactured solution as a forcing: initial state and per-step body force.

A scene with a ``[manufactured]`` table (amplitude ``A``) is driven so that the exact motion of
:func:`parmpm.exact.bars.manufactured_motion` solves it (docs/verification.md §3): every particle starts on
the exact field (``x = X + U``, ``v``, ``F = diag(F_kk)``, and the stress of that ``F``; CPDI's
``R = F·R0`` and cpGIMP's ``l0·|F_kk|`` follow from ``F``), and each step adds the body force
``m_p b(X_p, t)`` at the particle's *reference* position ``X_p`` and the step's start time ``t``
to the grid force (in ``p2g``). ``c = sqrt(E/ρ0)`` of the (single) material sets the frequency;
one period is ``T = 2/c``.
"""
from __future__ import annotations

import math

import numpy as np

from parmpm.exact.bars import manufactured_motion
from parmpm.core.jit import kernel
from parmpm.materials import COL_DENSITY, COL_E
from parmpm.materials.laws import cauchy_stress

__all__ = ["frequency", "initialise", "body_force"]


def frequency(params: np.ndarray) -> float:
    """``c = sqrt(E/ρ0)`` of the material (row 0 of the table; the scene has one material)."""
    return math.sqrt(params[0, COL_E] / params[0, COL_DENSITY])


def initialise(P, A: float, params: np.ndarray) -> None:
    """Put every particle of ``P`` on the exact field at ``t = 0`` (``P.x0`` holds ``X``)."""
    c = frequency(params)
    u, v, Fd = manufactured_motion(P.x0, 0.0, A, c)
    P.x[:] = P.x0 + u
    P.v[:] = v
    d = P.dim
    P.F[:] = 0.0
    for k in range(d):
        P.F[:, k, k] = Fd[:, k]
    for i in range(P.n):  # set-up only
        cauchy_stress(d, params[P.mat[i]], P.F[i], P.damage[i], P.stress[i])


@kernel
def body_force(d, x0, t, A, c, lam, mu, rho, out):
    """``out[p] = b(X_p, t)``: :func:`parmpm.exact.bars.manufactured_body_force` for the step."""
    pi = math.pi
    Fd = np.zeros(3)
    U = np.zeros(3)
    for i in range(x0.shape[0]):
        lnJ = 0.0
        for k in range(d):
            ph = c * pi * t + 2.0 * pi * k / 3.0
            s = math.sin(ph)
            U[k] = A * math.sin(pi * x0[i, k]) * s
            Fd[k] = 1.0 + A * pi * math.cos(pi * x0[i, k]) * s
            lnJ += math.log(Fd[k])
        for k in range(d):
            out[i, k] = pi * pi * U[k] * (mu / rho - c * c - (lam * (lnJ - 1.0) - mu) / (rho * Fd[k] * Fd[k]))
