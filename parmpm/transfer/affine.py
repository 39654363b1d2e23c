"""Affine particle-in-cell transfers (APIC; Jiang, Schroeder, Selle, Teran & Stomakhin 2015).

FLIP keeps a particle's velocity and adds the grid's increment; PIC replaces it by the grid's
interpolated velocity and so loses every velocity mode the particle cannot carry — rotation
included, which is why neither keeps the angular momentum of a spinning body. APIC gives each
particle an affine velocity field ``v(x) = v_p + C_p (x − x_p)`` and transfers it whole:

    P2G   (m v)_i = Σ_p w_ip m_p (v_p + C_p (x_i − x_p))
    G2P   v_p = Σ_i w_ip v_i,    C_p = Σ_i w_ip v_i ⊗ (x_i − x_p) · D_p⁻¹,
          D_p = Σ_i w_ip (x_i − x_p) ⊗ (x_i − x_p).

(``C_p = B_p D_p⁻¹`` in the paper's notation; parmpm stores ``C_p``, the particle field
``affine``.) For quadratic B-splines ``D_p = diag(Δx_k²/4)`` at every point — the variance of
the B-spline, the same for any position inside a cell — so ``D_p⁻¹`` is a constant and the
G2P/P2G pair conserves angular momentum exactly: the grid's ``Σ x_i × m_i v_i`` after P2G equals
the particles'

    l = Σ_p m_p (x_p × v_p + ε : (C_p D_p)ᵀ),   2D: l_z = Σ_p m_p (x_p v_py − y_p v_px
                                                            + C_yx Δx²/4 − C_xy Δy²/4),

and a symmetric stress exerts no torque on the grid, so ``l`` changes only by round-off (tested
on the spinning disk). For the linear hat ``D_p`` is singular on a node, and for the domain
methods it depends on the domain: APIC is offered with ``bspline`` only.

MLS-MPM (``transfer = "mls"``; Hu, Fang, Ge, Qu, Zhu, Pradhana & Jiang 2018) keeps APIC's
transfers and replaces the weight gradient by the moving-least-squares one,
``∇̃φ_ip = φ_ip D_p⁻¹ (x_i − x_p)``, everywhere the gradient appears:

    force      f_i = −Σ_p V_p σ_p ∇̃φ_ip = −Σ_p φ_ip V_p σ_p D⁻¹ (x_i − x_p),
    gradient   L_p = Σ_i v_i ⊗ ∇̃φ_ip = C_p   (the affine matrix itself).

``Σ_i φ_ip r ⊗ r = D`` makes ``∇̃φ`` reproduce linear fields (``L_p`` is exact for an affine
grid velocity) and the force torque-free (``Σ_i r × σ D⁻¹ r φ = ε : σᵀ = 0`` for a symmetric
``σ``), so angular momentum is kept as under APIC. The force has the momentum's weights, so P2G
adds ``Δt f_i`` to the scattered momentum and the grid carries ``(m, mv + Δt f)`` only: per node
three sums in 2D instead of five, the saving the method is used for (docs/mls.md).
"""
from __future__ import annotations

import numpy as np

from parmpm.shapes import BSPLINE

#: the transfer schemes of ``method.transfer``
TRANSFERS = ("flip", "apic", "mls")
#: the transfers that carry the affine matrix ``C_p`` on the particle
AFFINE_TRANSFERS = ("apic", "mls")
#: interpolators whose ``D_p`` is a constant diagonal (what APIC and MLS need here)
APIC_INTERPOLATORS = ("bspline",)


def inertia_diagonal(method: int, h: np.ndarray, affine: bool) -> np.ndarray:
    """``diag D_p`` (physical units, per axis) of an APIC or MLS run; zeros under FLIP (so the
    affine term of the angular momentum vanishes)."""
    h = np.asarray(h, float)
    if not affine:
        return np.zeros(h.size)
    if method != BSPLINE:
        raise ValueError("APIC and MLS need the bspline interpolator")
    return 0.25 * h * h

