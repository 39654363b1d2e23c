"""Every elastic law's stress against closed forms, through every form a kernel calls
(:mod:`parmpm.materials.laws`): the generic ``cauchy_stress`` (1D, 2D, 3D) and the specialised
kernels' ``stress_speed_2d`` / ``stress_speed_3d``.

Nothing else in the suite pins a law's formula on its own: the runs judge the laws through
whole-scene results (a bar's peak, a convergence order), which a 1 % error in the neo-Hookean
shear stress left inside their tolerances (a planted error of that size went through the whole
suite unnoticed), and the specialised kernels are compared with the generic ones, which share
the law. Here each formula meets an independent result:

* simple shear ``F = I + γ e_x ⊗ e_y`` (``J = 1``): neo-Hookean ``σ_xy = μγ``, ``σ_xx = μγ²``,
  ``σ_yy = σ_zz = 0``; small-strain linear elasticity ``σ_xy = μγ``, no normal stress;
* uniaxial stretch ``F = diag(s, 1, 1)``: neo-Hookean ``σ_xx = [μ(s² − 1) + λ ln s]/s``,
  ``σ_yy = σ_zz = λ ln s / s``; linear ``σ_xx = (λ + 2μ)(s − 1)``, ``σ_yy = σ_zz = λ(s − 1)``;
* the stress is the derivative of the law's own stored energy at a random ``F``: Kirchhoff
  ``Jσ = (∂ψ/∂F) Fᵀ`` (neo-Hookean), ``σ = sym ∂ψ/∂F`` (linear), by central differences of
  ``stored_energy`` — code that shares nothing with the stress's.
"""
import math

import numpy as np
import pytest

from parmpm.materials import (COL_C2, COL_DENSITY, COL_INV_DENSITY, COL_LAM, COL_LAW, COL_MU,
                              MODELS, N_PARAMS, lame)
from parmpm.materials.laws import (cauchy_stress, stored_energy, stress_speed_2d, stress_speed_3d,
                                   wave_speed)

E, NU, RHO = 2.0e6, 0.3, 1200.0
LAM, MU = lame(E, NU)
LAWS = sorted(MODELS)


def params(model: str) -> np.ndarray:
    """One material's row of the parameter table (:func:`parmpm.materials.material_table`)."""
    table = np.zeros((1, N_PARAMS))
    table[0, COL_LAW], table[0, COL_DENSITY] = MODELS[model], RHO
    table[0, COL_LAM], table[0, COL_MU] = LAM, MU
    table[0, COL_C2], table[0, COL_INV_DENSITY] = (LAM + 2 * MU) / RHO, 1 / RHO
    return table


def generic(model: str, d: int, F: np.ndarray) -> np.ndarray:
    """The generic kernels' stress: the leading d×d block of a 3×3 array."""
    F3, out = np.eye(3), np.zeros((3, 3))
    F3[:d, :d] = F[:d, :d]
    cauchy_stress(d, params(model)[0], F3, 0.0, out)
    return out[:d, :d]


def specialised(model: str, d: int, F: np.ndarray) -> np.ndarray:
    """The specialised kernels' stress, as a symmetric d×d matrix."""
    F3 = np.eye(3)
    F3[:d, :d] = F[:d, :d]
    if d == 2:
        sxx, sxy, syy, c2, _ = stress_speed_2d(params(model), 0, F[0, 0], F[0, 1], F[1, 0],
                                               F[1, 1])
        out = np.array([[sxx, sxy], [sxy, syy]])
    else:
        sxx, sxy, sxz, syy, syz, szz, c2, _ = stress_speed_3d(params(model), 0,
                                                              *F[:3, :3].ravel())
        out = np.array([[sxx, sxy, sxz], [sxy, syy, syz], [sxz, syz, szz]])
    # the squared CFL speed: the generic kernels' wave speed, squared
    assert math.sqrt(c2) == pytest.approx(wave_speed(d, params(model)[0], F3), rel=1e-14)
    return out


FORMS = [("generic", 1), ("generic", 2), ("generic", 3), ("specialised", 2), ("specialised", 3)]


def stress(form: str, model: str, d: int, F: np.ndarray) -> np.ndarray:
    return (generic if form == "generic" else specialised)(model, d, F)


def close(got, want):
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12 * MU)


@pytest.mark.parametrize("form,d", [f for f in FORMS if f[1] > 1])
@pytest.mark.parametrize("model", LAWS)
def test_simple_shear(form, d, model):
    gamma = 0.3
    F = np.eye(3)
    F[0, 1] = gamma
    want = np.zeros((d, d))
    want[0, 1] = want[1, 0] = MU * gamma
    if model == "neo_hookean":
        want[0, 0] = MU * gamma**2  # b = F Fᵀ: b_xx = 1 + γ², b_yy = 1, J = 1
    close(stress(form, model, d, F[:d, :d]), want)


@pytest.mark.parametrize("form,d", FORMS)
@pytest.mark.parametrize("model", LAWS)
@pytest.mark.parametrize("s", [0.8, 1.2])
def test_uniaxial_stretch(form, d, model, s):
    F = np.diag([s, 1.0, 1.0])
    if model == "neo_hookean":
        axial, lateral = (MU * (s * s - 1) + LAM * math.log(s)) / s, LAM * math.log(s) / s
    else:
        axial, lateral = (LAM + 2 * MU) * (s - 1), LAM * (s - 1)
    want = np.diag([axial] + [lateral] * (d - 1))
    close(stress(form, model, d, F[:d, :d]), want)


def energy_gradient(model: str, d: int, F: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """∂ψ/∂F by central differences of the law's stored energy (fourth order: two step sizes)."""
    row = params(model)[0]

    def psi(G):
        G3 = np.eye(3)
        G3[:d, :d] = G
        return stored_energy(d, row, G3, 0.0)

    grad = np.zeros((d, d))
    for a in range(d):
        for b in range(d):
            dF = np.zeros((d, d))
            dF[a, b] = h
            d1 = (psi(F + dF) - psi(F - dF)) / (2 * h)
            d2 = (psi(F + 2 * dF) - psi(F - 2 * dF)) / (4 * h)
            grad[a, b] = (4 * d1 - d2) / 3
    return grad


@pytest.mark.parametrize("form,d", [f for f in FORMS if f[1] > 1])
@pytest.mark.parametrize("model", LAWS)
def test_stress_is_the_derivative_of_the_stored_energy(form, d, model):
    rng = np.random.default_rng(7 + d)
    F = np.eye(d) + rng.uniform(-0.25, 0.25, (d, d))
    P = energy_gradient(model, d, F)
    if model == "neo_hookean":
        want = P @ F.T / np.linalg.det(F)   # Cauchy from the first Piola-Kirchhoff stress
    else:
        want = 0.5 * (P + P.T)              # small strain: σ = ∂ψ/∂ε
    got = stress(form, model, d, F)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-6 * np.abs(want).max())
