"""Material registry: the elastic laws and damage softenings by name, and the parameter table.

Nothing here compiles: reading or checking a scene needs the names, not the kernels. Each
material is a row of a float64 table so kernels need no objects; its columns are named once
(``COL_*``, :data:`PARAM`): ``[law code, ρ0, E, ν, λ, μ, c², 1/ρ0, damage softening, λ0, λf,
D_freeze]`` with ``c² = (λ + 2μ)/ρ0`` the P-wave speed squared (``1/ρ0`` spares the hot loops a
division); the last four describe the damage model (:mod:`parmpm.materials.damage`; zeros:
none). The kernels are in :mod:`parmpm.materials.laws` (the one switch over the laws), the laws'
formulas in one module each.

To add a law: a module beside :mod:`parmpm.materials.neo_hookean` with its generic and scalar
2D/3D forms, a :class:`Law` entry below, and its branch in :mod:`parmpm.materials.laws` (which
refuses to import while a registered law has no branch).
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Law:
    name: str
    code: int
    summary: str


LINEAR_ELASTIC, NEO_HOOKEAN = 0, 1
LAWS = {law.name: law for law in (
    Law("linear_elastic", LINEAR_ELASTIC,
        "small-strain isotropic elasticity, sigma = lambda tr(eps) I + 2 mu eps"),
    Law("neo_hookean", NEO_HOOKEAN,
        "compressible neo-Hookean, sigma = [mu (b - I) + lambda ln J I] / J"),
)}
#: law name → code (the table's first column)
MODELS = {name: law.code for name, law in LAWS.items()}

J2, DRUCKER_PRAGER = 1, 2
#: the plastic models (:mod:`parmpm.materials.plasticity`) by name → their code in the plastic
#: table (:mod:`parmpm.materials.plasticity.table`; 0: an elastic material). A plastic material's
#: row of the parameter table tells the fused elastic update it has no elastic response of its
#: own (law ``linear_elastic`` with λ = μ = c² = 0: zero stress, zero wave speed); the plastic
#: pass after G2P writes its stress and speed. So the elastic kernels compile and run unchanged.
PLASTIC_MODELS = {"j2": J2, "drucker_prager": DRUCKER_PRAGER}

NO_DAMAGE, LINEAR, EXPONENTIAL = 0, 1, 2
#: damage softening name → code (the table's ``damage`` column; 0: no damage model)
SOFTENING = {"linear": LINEAR, "exponential": EXPONENTIAL}

(COL_LAW, COL_DENSITY, COL_E, COL_NU, COL_LAM, COL_MU, COL_C2, COL_INV_DENSITY,
 COL_DAMAGE, COL_ONSET, COL_FRACTURE, COL_FREEZE) = range(12)
PARAM = {"model": COL_LAW, "density": COL_DENSITY, "E": COL_E, "nu": COL_NU, "lam": COL_LAM,
         "mu": COL_MU, "c2": COL_C2, "inv_density": COL_INV_DENSITY, "damage": COL_DAMAGE,
         "damage_onset": COL_ONSET, "damage_fracture": COL_FRACTURE,
         "damage_freeze": COL_FREEZE}
N_PARAMS = len(PARAM)
#: the damage-freeze column's value for ``freeze = "never"`` (a damage D ≤ 1 never reaches it)
FREEZE_NEVER = 2.0


def lame(E: float, nu: float) -> tuple[float, float]:
    """Lamé constants (λ, μ) from Young's modulus and Poisson's ratio."""
    return E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))


def material_table(materials: Mapping) -> tuple[np.ndarray, list[str]]:
    """Parameter table (n_materials, N_PARAMS) and the material names in row order, from the
    scene's material records by name (:class:`parmpm.scene.records.Material`: ``model``,
    ``density``, ``youngs_modulus``, ``poisson_ratio``, ``damage``)."""
    names = sorted(materials)
    table = np.zeros((len(names), N_PARAMS))
    for row, name in enumerate(names):
        m = materials[name]
        E, nu, rho = m.youngs_modulus, m.poisson_ratio, m.density
        lam, mu = lame(E, nu)
        r = table[row]
        r[COL_DENSITY], r[COL_E], r[COL_NU], r[COL_INV_DENSITY] = rho, E, nu, 1 / rho
        if m.model in PLASTIC_MODELS:  # the plastic pass's (module docstring of PLASTIC_MODELS)
            r[COL_LAW] = LINEAR_ELASTIC
            continue
        r[COL_LAW], r[COL_LAM], r[COL_MU] = MODELS[m.model], lam, mu
        r[COL_C2] = (lam + 2 * mu) / rho
        dmg = m.damage
        if dmg:
            r[COL_DAMAGE], r[COL_ONSET] = SOFTENING[dmg.softening], dmg.onset
            r[COL_FRACTURE] = dmg.fracture
            r[COL_FREEZE] = FREEZE_NEVER if dmg.freeze == "never" else dmg.freeze
    return table, names


__all__ = ["LAWS", "MODELS", "PLASTIC_MODELS", "SOFTENING", "PARAM", "N_PARAMS", "Law", "lame", "material_table"]
