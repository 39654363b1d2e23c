"""Material registry and the stress kernel's single dispatch.

Each material is a row of a float64 parameter table (see ``PARAM``) so kernels need no objects:
``[model code, ρ0, E, ν, λ, μ, c², 1/ρ0, damage model, λ0, λf, D_freeze]`` with
``c² = (λ + 2μ)/ρ0`` the P-wave speed squared used for the CFL time step (``1/ρ0`` spares the hot
loop a division); the last four describe the damage model (:mod:`parmpm.materials.damage`;
zeros: none). ``cauchy_stress`` gives the elastic stress degraded by the particle's damage.
"""
from __future__ import annotations

import math

import numpy as np

from parmpm.jit import helper_kernel
from parmpm.materials.damage import SOFTENING, degrade, pressure_term
from parmpm.materials.linear_elastic import linear_elastic_energy, linear_elastic_stress
from parmpm.materials.neo_hookean import det_d, neo_hookean_energy, neo_hookean_stress

LINEAR_ELASTIC, NEO_HOOKEAN = 0, 1
MODELS = {"linear_elastic": LINEAR_ELASTIC, "neo_hookean": NEO_HOOKEAN}
PARAM = {"model": 0, "density": 1, "E": 2, "nu": 3, "lam": 4, "mu": 5, "c2": 6, "inv_density": 7,
         "damage": 8, "damage_onset": 9, "damage_fracture": 10, "damage_freeze": 11}
N_PARAMS = 12


def lame(E: float, nu: float) -> tuple[float, float]:
    """Lamé constants (λ, μ) from Young's modulus and Poisson's ratio."""
    return E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))


def material_table(materials: dict) -> tuple[np.ndarray, list[str]]:
    """Parameter table (n_materials, N_PARAMS) and the material names in row order."""
    names = sorted(materials)
    table = np.zeros((len(names), N_PARAMS))
    for row, name in enumerate(names):
        m = materials[name]
        lam, mu = lame(m["youngs_modulus"], m["poisson_ratio"])
        table[row, :8] = [MODELS[m["model"]], m["density"], m["youngs_modulus"],
                          m["poisson_ratio"], lam, mu, (lam + 2 * mu) / m["density"], 1 / m["density"]]
        dmg = m.get("damage")
        if dmg:
            freeze = 2.0 if dmg["freeze"] == "never" else dmg["freeze"]  # 2: never reached
            table[row, 8:] = [SOFTENING[dmg["softening"]], dmg["onset"], dmg["fracture"], freeze]
    return table, names


@helper_kernel
def cauchy_stress(d, params, F, damage, out):
    """Cauchy stress of one particle from its deformation gradient (leading d×d of 3×3 arrays)."""
    model = int(params[0])
    if model == LINEAR_ELASTIC:
        linear_elastic_stress(d, F, params[4], params[5], out)
    else:
        neo_hookean_stress(d, F, params[4], params[5], out)
    if damage > 0.0:
        tr = 0.0
        for a in range(d):
            tr += F[a, a] - 1.0
        degrade(d, damage, pressure_term(model == LINEAR_ELASTIC, params[4], det_d(d, F), tr), out)


@helper_kernel
def stored_energy(d, params, F, damage):
    """Elastic energy per unit reference volume of one particle, ``(1 − D) ψ(F)``.

    The damaged law keeps a compressive pressure on broken particles, whose energy this leaves
    out: an underestimate, which is the safe side for the run's blow-up watch
    (:mod:`parmpm.energy`)."""
    if int(params[0]) == LINEAR_ELASTIC:
        psi = linear_elastic_energy(d, F, params[4], params[5])
    else:
        psi = neo_hookean_energy(d, F, params[4], params[5])
    return (1.0 - damage) * psi


@helper_kernel
def wave_speed(d, params, F):
    """Largest wave speed in the *current* configuration, for the CFL step.

    A stretched body carries waves faster across a fixed grid: in 1D neo-Hookean the spatial
    speed is ``c² = λ² ∂P/∂λ / ρ0 = [μ(λ² + 1) + λ_L(1 − ln λ)] / ρ0``, which at large stretch far
    exceeds the reference ``(λ_L + 2μ)/ρ0``. We use ``[μ(b_max + 1) + λ_L·max(1, 1 − ln J)] / ρ0``
    with ``b_max`` (Gershgorin bound of the largest eigenvalue of ``b = F Fᵀ``), exact in 1D and
    equal to the P-wave speed at ``F = I``; linear elasticity scales ``c0²`` by ``max(1, b_max)``.
    """
    bmax = 0.0
    for a in range(d):
        row = 0.0
        for b in range(d):
            bab = 0.0
            for k in range(d):
                bab += F[a, k] * F[b, k]
            row += abs(bab)
        bmax = max(bmax, row)
    J = det_d(d, F)
    if not J > 0.0:
        return math.inf
    if int(params[0]) == LINEAR_ELASTIC:
        return math.sqrt(params[6] * max(1.0, bmax))
    lam, mu = params[4], params[5]
    return math.sqrt((mu * (bmax + 1.0) + lam * max(1.0, 1.0 - math.log(J))) / params[1])


__all__ = ["MODELS", "wave_speed", "PARAM", "material_table", "cauchy_stress", "stored_energy", "lame", "det_d"]
