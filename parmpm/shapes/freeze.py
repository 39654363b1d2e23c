"""Damage-triggered domain freeze: the coupling of the damage model to CPDI (Homel's point that
the freeze should be "triggered by the constitutive model if material is damaged").

Choice: a frozen domain keeps rotating with the material. At the first step where a particle's
damage reaches its material's ``freeze`` value, its domain ``R = F·R0`` is stored in the
material's unrotated frame, ``rf = Rᵀ_F·R = U·R0`` (polar decomposition ``F = R_F·U``). From then
on its domain is ``R = R_F(t)·rf``: the shape it had when the material failed, turned with the
material, but no longer stretched. As a crack opens, the frozen domains on its two sides stop
filling the gap, their supports part by a grid cell, and the pieces separate — while undamaged
particles keep full CPDI. Why rotate rather than freeze ``R`` itself: a fragment that spins after
failing must keep its domain on its material (a fixed ``R`` would slide its corners off it), and
the stretch and rotation at the moment of failure are preserved, as the seed asks.

Every kernel forms ``R = F·r0``. Instead of threading a flag through all of them, a frozen
particle's ``r0`` is reset after each deformation update to ``r0 = F⁻¹·R_F·rf``, so that
``F·r0 = R_F·rf`` wherever a domain is formed (domain scaling by ``l_cr`` still applies on top).
``rf = 0`` marks a particle that is not frozen. Only particles whose material has a damage model
are visited.

CPDI2 (tracked corners, :mod:`parmpm.shapes.cpdi2`) freezes the same way here; its weights read
neither ``r0`` nor ``rf``, but G2P stops moving a frozen particle's corners relative to it
(:mod:`parmpm.transfer.generic`; the choice is discussed in ``docs/cpdi2.md``).
"""
import math

import numpy as np

from parmpm.core.jit import kernel
from parmpm.materials import COL_DAMAGE, COL_FREEZE
from parmpm.shapes.cpdi import cofactor


@kernel
def polar_rotation(d, F, Q):
    """The rotation ``R_F`` of ``F = R_F·U`` (``det F > 0``) into ``Q`` (leading d×d): closed
    form in 1D and 2D, Newton's iteration ``X ← (X + X⁻ᵀ)/2`` in 3D (quadratic convergence)."""
    if d == 1:
        Q[0, 0] = 1.0 if F[0, 0] > 0 else -1.0
        return
    if d == 2:
        th = math.atan2(F[1, 0] - F[0, 1], F[0, 0] + F[1, 1])
        c, s = math.cos(th), math.sin(th)
        Q[0, 0], Q[0, 1], Q[1, 0], Q[1, 1] = c, -s, s, c
        return
    X = np.empty((3, 3))
    Y = np.empty((3, 3))
    for a in range(3):
        for b in range(3):
            X[a, b] = F[a, b]
    for _ in range(60):
        inverse_transpose3(X, Y)
        change = 0.0
        for a in range(3):
            for b in range(3):
                nxt = 0.5 * (X[a, b] + Y[a, b])
                change = max(change, abs(nxt - X[a, b]))
                X[a, b] = nxt
        if change < 1e-15:
            break
    for a in range(3):
        for b in range(3):
            Q[a, b] = X[a, b]


@kernel
def inverse_transpose3(X, out):
    """``out = X⁻ᵀ = cof(X)/det X`` (3×3), by :func:`parmpm.shapes.cpdi.cofactor`."""
    det = cofactor(3, X, out)
    for a in range(3):
        for b in range(3):
            out[a, b] /= det


@kernel
def transpose_times(d, A, B, C, out):
    """``out = Aᵀ·B·C`` (d × d), summed as ``Σ_k A[k, a] (Σ_m B[k, m] C[m, b])``."""
    for a in range(d):
        for b in range(d):
            acc = 0.0
            for k in range(d):
                BC = 0.0
                for m in range(d):
                    BC += B[k, m] * C[m, b]
                acc += A[k, a] * BC
            out[a, b] = acc


@kernel
def freeze_domains(d, F, r0, rf, damage, mat, params):
    """Freeze the domains of particles whose damage reached their material's ``freeze`` value
    and keep every frozen domain at ``R = R_F·rf`` (module docstring). Returns how many
    particles are frozen."""
    Q = np.zeros((3, 3))
    Fi = np.zeros((3, 3))
    FinvT = np.zeros((3, 3))
    frozen = 0
    for i in range(F.shape[0]):
        row = mat[i]
        if params[row, COL_DAMAGE] == 0.0:
            continue
        is_frozen = False
        for a in range(d):
            if rf[i, a, 0] != 0.0:
                is_frozen = True
        if not is_frozen and not damage[i] >= params[row, COL_FREEZE]:
            continue
        for a in range(d):
            for b in range(d):
                Fi[a, b] = F[i, a, b]
        polar_rotation(d, Fi, Q)
        if not is_frozen:  # rf = Qᵀ·F·r0 (= U·R0): the domain now, unrotated
            transpose_times(d, Q, F[i], r0[i], rf[i])
        frozen += 1
        # r0 = F⁻¹·Q·rf
        if d == 1:
            r0[i, 0, 0] = Q[0, 0] * rf[i, 0, 0] / F[i, 0, 0]
            continue
        if d == 2:
            det = Fi[0, 0] * Fi[1, 1] - Fi[0, 1] * Fi[1, 0]
            FinvT[0, 0], FinvT[0, 1] = Fi[1, 1] / det, -Fi[1, 0] / det
            FinvT[1, 0], FinvT[1, 1] = -Fi[0, 1] / det, Fi[0, 0] / det
        else:
            inverse_transpose3(Fi, FinvT)
        transpose_times(d, FinvT, Q, rf[i], r0[i])  # F⁻¹ = (F⁻ᵀ)ᵀ
    return frozen
