"""The plastic table: one float64 row per material (the parameter table's row order), the
constants the plastic pass reads, so kernels need no objects.

Columns (``PCOL_*``): ``[model code (0: elastic, J2, DRUCKER_PRAGER), K, G, c0² = (K + 4G/3)/ρ0,
hardening code, a, b, n, c, rate0, η, ξ, η̄, cohesion, p_t, volume correction (1.0 or 0.0), η_2,
I_0, d √ρ_s]``, the last three μ(I)'s (``I_0 = 0``: off, :mod:`.inertial`); the hardening constants are
:mod:`.hardening`'s ``(a, b, n, c, rate0)``, the Drucker–Prager ones
:func:`.drucker_prager.drucker_prager_constants`'. Only a scene with a plastic material has one
(:func:`plastic_table` returns None otherwise): an elastic scene builds nothing here.
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from parmpm.materials import PLASTIC_MODELS, J2, DRUCKER_PRAGER
from parmpm.materials.plasticity.drucker_prager import drucker_prager_constants
from parmpm.materials.plasticity.hardening import HARDENING, JOHNSON_COOK, LINEAR, SWIFT, swift_eps0

(PCOL_MODEL, PCOL_K, PCOL_G, PCOL_C2, PCOL_HARDENING, PCOL_A, PCOL_B, PCOL_N, PCOL_C, PCOL_RATE0,
 PCOL_ETA, PCOL_XI, PCOL_ETA_BAR, PCOL_COHESION, PCOL_PT, PCOL_VOLUME_CORRECTION, PCOL_ETA_2,
 PCOL_I0, PCOL_GRAIN_SCALE) = range(19)
N_PLASTIC = 19


def bulk_shear(E: float, nu: float) -> tuple[float, float]:
    """Hencky's bulk and shear moduli ``(K, G)`` from Young's modulus and Poisson's ratio."""
    return E / (3.0 * (1.0 - 2.0 * nu)), E / (2.0 * (1.0 + nu))


def _hardening_constants(m) -> tuple[int, float, float, float, float, float]:
    """``(code, a, b, n, c, rate0)`` of a J2 material record."""
    code = HARDENING[m.hardening or "linear"]
    sy0 = m.yield_stress
    if code == LINEAR:
        return LINEAR, sy0, m.hardening_modulus or 0.0, 1.0, 0.0, 1.0
    if code == SWIFT:
        A, n = m.strength_coefficient, m.hardening_exponent
        return SWIFT, A, swift_eps0(sy0, A, n), n, 0.0, 1.0
    return (JOHNSON_COOK, sy0, m.hardening_modulus or 0.0, m.hardening_exponent,
            m.rate_coefficient or 0.0, m.reference_rate or 1.0)


def plastic_table(materials: Mapping, names: Sequence[str]) -> np.ndarray | None:
    """``(len(names), N_PLASTIC)`` rows of the plastic constants in ``names``' order (the
    parameter table's, :func:`parmpm.materials.material_table`), or None when no material is
    plastic. ``materials``: the scene's records by name (:class:`parmpm.scene.records.Material`)."""
    if not any(materials[n].model in PLASTIC_MODELS for n in names):
        return None
    table = np.zeros((len(names), N_PLASTIC))
    for row, name in enumerate(names):
        m = materials[name]
        code = PLASTIC_MODELS.get(m.model, 0)
        if code == 0:
            continue
        r = table[row]
        K, G = bulk_shear(m.youngs_modulus, m.poisson_ratio)
        r[PCOL_MODEL], r[PCOL_K], r[PCOL_G] = code, K, G
        r[PCOL_C2] = (K + 4.0 * G / 3.0) / m.density
        if code == J2:
            (r[PCOL_HARDENING], r[PCOL_A], r[PCOL_B], r[PCOL_N], r[PCOL_C],
             r[PCOL_RATE0]) = _hardening_constants(m)
        elif code == DRUCKER_PRAGER:
            cohesion = m.cohesion or 0.0
            eta, xi, eta_bar, p_t = drucker_prager_constants(
                m.friction_angle, m.dilatancy_angle or 0.0, cohesion, m.matching or "plane_strain",
                m.tension_cutoff, where=f"materials.{name}")
            r[PCOL_ETA], r[PCOL_XI], r[PCOL_ETA_BAR] = eta, xi, eta_bar
            r[PCOL_COHESION], r[PCOL_PT] = cohesion, p_t
            r[PCOL_VOLUME_CORRECTION] = 1.0 if m.volume_correction else 0.0
            if m.friction_angle_2 is not None:  # μ(I): the slope at large I, I_0, d √ρ_s
                r[PCOL_ETA_2] = drucker_prager_constants(
                    m.friction_angle_2, 0.0, 0.0, m.matching or "plane_strain", where=f"materials.{name}")[0]
                r[PCOL_I0] = m.inertial_number_0
                r[PCOL_GRAIN_SCALE] = m.grain_diameter * math.sqrt(
                    m.grain_density or m.density)
    return table
