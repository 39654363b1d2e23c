"""Exact solutions against closed forms and against each other (docs/verification.md §1, §2)."""

import math

import numpy as np
import pytest

from parmpm.core.errors import SceneError
from parmpm.exact.bars import (hanging_bar_dynamic_series, hanging_bar_dynamic_tip, hanging_bar_static,
                          hanging_bar_static_displacement, nominal_stress_1d,
                          vibrating_bar_com_velocity, vibrating_bar_fields)

E, RHO, L, V0 = 100.0, 1.0, 25.0, 0.1


@pytest.mark.parametrize("mode", [1, 2, 3])
def test_com_velocity_is_mean_of_velocity_field(mode):
    X = np.linspace(0.0, L, 20001)
    for t in (0.0, 1.3, 7.7):
        _, v, _ = vibrating_bar_fields(X, t, V0, L, E, RHO, mode)
        mean = np.trapezoid(v, X) / L
        assert vibrating_bar_com_velocity(t, V0, L, E, RHO, mode) == pytest.approx(mean, abs=1e-9)


def test_vibrating_bar_period_and_array_time():
    t = np.array([0.0, 5.0, 10.0])  # mode 1: period 4L/c = 10 s
    vbar = vibrating_bar_com_velocity(t, V0, L, E, RHO)
    amp = V0 / (math.pi / (2 * L) * L)
    np.testing.assert_allclose(vbar, [amp, -amp, amp], rtol=1e-12)


def test_vibrating_bar_fields_satisfy_pde_and_bcs():
    c = math.sqrt(E / RHO)
    X = np.linspace(0.0, L, 201)[:, None]
    t = np.linspace(0.0, 10.0, 7)[None, :]
    h = 1e-4
    u, v, s = vibrating_bar_fields(X, t, V0, L, E, RHO)
    # v = du/dt, sigma = E du/dX, rho dv/dt = dsigma/dX
    up, _, _ = vibrating_bar_fields(X, t + h, V0, L, E, RHO)
    um, _, _ = vibrating_bar_fields(X, t - h, V0, L, E, RHO)
    np.testing.assert_allclose((up - um) / (2 * h), v, atol=1e-8)
    uXp, _, sXp = vibrating_bar_fields(X + h, t, V0, L, E, RHO)
    uXm, _, sXm = vibrating_bar_fields(X - h, t, V0, L, E, RHO)
    np.testing.assert_allclose(E * (uXp - uXm) / (2 * h), s, atol=1e-7)
    _, vp, _ = vibrating_bar_fields(X, t + h, V0, L, E, RHO)
    _, vm, _ = vibrating_bar_fields(X, t - h, V0, L, E, RHO)
    np.testing.assert_allclose(RHO * (vp - vm) / (2 * h), (sXp - sXm) / (2 * h), atol=1e-6)
    np.testing.assert_allclose(u[0], 0.0, atol=1e-15)  # fixed end
    np.testing.assert_allclose(s[-1], 0.0, atol=1e-12)  # free end
    # energy per unit area rho v0^2 L / 4
    Xf = np.linspace(0.0, L, 20001)
    for tt in (0.0, 2.1, 4.4):
        _, vf, sf = vibrating_bar_fields(Xf, tt, V0, L, E, RHO)
        energy = np.trapezoid(0.5 * RHO * vf**2 + 0.5 * sf**2 / E, Xf)
        assert energy == pytest.approx(RHO * V0**2 * L / 4, rel=1e-8)
    assert c == 10.0


def test_linear_law_elongation():
    rho, g, Eb, Lb = 1050.0, 10.0, 1e6, 1.0
    k = rho * g / Eb
    res = hanging_bar_static(Lb, rho, g, lambda s: Eb * (s - 1.0))
    assert res["elongation"] == pytest.approx(k * Lb**2 / 2, rel=1e-10)
    np.testing.assert_allclose(res["stretch"], 1 + k * (Lb - res["X"]), rtol=1e-13)
    assert res["x"][0] == 0.0 and res["x"][-1] == pytest.approx(Lb + k * Lb**2 / 2, rel=1e-13)


def test_hypoelastic_log_law_elongation():
    rho, g, Eb, Lb = 1.0, 1.0, 1.0, 1.3
    k = rho * g / Eb
    res = hanging_bar_static(Lb, rho, g, lambda s: Eb * np.log(s))
    exact = (math.exp(k * Lb) - 1) / k - Lb
    assert res["elongation"] == pytest.approx(exact, rel=1e-9)


def _G(s):
    return 0.5 * (s * math.sqrt(1 + s * s) + math.asinh(s))


@pytest.mark.parametrize("kL", [0.1, 1.05, 3.0])
def test_neo_hookean_nu0_elongation(kL):
    Lb, Eb = 1.0, 1e6
    rho = 1050.0
    g = kL * Eb / (rho * Lb)
    k = kL / Lb
    res = hanging_bar_static(Lb, rho, g, nominal_stress_1d("neo_hookean", Eb, 0.0))
    exact = k * Lb**2 / 2 + (_G(kL) - _G(0.0)) / k - Lb
    assert res["elongation"] == pytest.approx(exact, rel=1e-10)
    assert res["top_stretch"] == pytest.approx(kL + math.sqrt(1 + kL**2), rel=1e-13)


def test_seed_case():
    res = hanging_bar_static(1.0, 1050.0, 1000.0, nominal_stress_1d("neo_hookean", 1e6, 0.0))
    assert res["top_stretch"] == pytest.approx(2.5, rel=1e-13)
    assert res["elongation"] == pytest.approx(0.6863, abs=5e-5)


def test_nominal_stress_laws():
    Eb, nu = 1e6, 0.3
    lam = Eb * nu / ((1 + nu) * (1 - 2 * nu))
    mu = Eb / (2 * (1 + nu))
    s = np.array([0.5, 1.0, 1.7])
    np.testing.assert_allclose(nominal_stress_1d("linear_elastic", Eb, nu)(s), (lam + 2 * mu) * (s - 1))
    nh = nominal_stress_1d("neo_hookean", Eb, nu)
    np.testing.assert_allclose(nh(s), (mu * (s**2 - 1) + lam * np.log(s)) / s)
    assert nh(np.array([1.0]))[0] == 0.0
    # small strain: NH tangent at lambda = 1 is lambda_L + 2 mu
    h = 1e-6
    assert (nh(1 + h) - nh(1 - h)) / (2 * h) == pytest.approx(lam + 2 * mu, rel=1e-8)
    np.testing.assert_allclose(nominal_stress_1d("neo_hookean", Eb, 0.0)(s), Eb / 2 * (s - 1 / s))
    with pytest.raises(SceneError):
        nominal_stress_1d("plasticine", Eb, nu)


def test_scalar_only_law_and_compression():
    # a callable that only takes scalars, and a negative load (g < 0: compression)
    res = hanging_bar_static(2.0, 1.0, -0.2, lambda s: 3.0 * (float(s) - 1.0), n=101)
    assert res["elongation"] == pytest.approx(-0.2 / 3.0 * 2.0**2 / 2, rel=1e-10)
    assert res["top_stretch"] < 1.0


def test_dynamic_tip_piecewise_and_series():
    Lb, rho, g, Eb = 2.0, 3.0, 9.81, 50.0
    c = math.sqrt(Eb / rho)
    T = 4 * Lb / c
    t = np.linspace(0.0, 2.5 * T, 41)
    tip = hanging_bar_dynamic_tip(t, Lb, rho, g, Eb)
    series = hanging_bar_dynamic_series(Lb, t, Lb, rho, g, Eb, n_modes=4000)
    static_tip = g * Lb**2 / (2 * c**2)
    np.testing.assert_allclose(tip, series, atol=1e-6 * static_tip)
    assert hanging_bar_dynamic_tip(2 * Lb / c, Lb, rho, g, Eb) == pytest.approx(2 * static_tip)
    t1 = 0.3 * Lb / c
    assert hanging_bar_dynamic_tip(t1, Lb, rho, g, Eb) == pytest.approx(0.5 * g * t1**2)
    np.testing.assert_allclose(hanging_bar_dynamic_tip(t + T, Lb, rho, g, Eb), tip, atol=1e-12)
    # mean over a period is the static tip displacement
    tt = np.linspace(0.0, T, 40001)
    mean = np.trapezoid(hanging_bar_dynamic_tip(tt, Lb, rho, g, Eb), tt) / T
    assert mean == pytest.approx(static_tip, rel=1e-6)


def test_static_displacement_at_points_matches_profile():
    law = nominal_stress_1d("neo_hookean", 1e6, 0.0)
    prof = hanging_bar_static(1.0, 1050.0, 1000.0, law, n=2001)
    X = np.array([0.0, 0.25, 0.5, 1.0])
    u = hanging_bar_static_displacement(X, 1.0, 1050.0, 1000.0, law)
    idx = [0, 500, 1000, 2000]
    np.testing.assert_allclose(u, prof["x"][idx] - prof["X"][idx], rtol=1e-11, atol=1e-15)
    assert float(hanging_bar_static_displacement(1.0, 1.0, 1050.0, 1000.0, law)) == pytest.approx(
        prof["elongation"], rel=1e-12
    )
