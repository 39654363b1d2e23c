"""The plastic pass (:mod:`parmpm.materials.plasticity.update`) against the return maps driven
the way the material-point tests drive them: the pass keeps ``C_p⁻¹`` and forms
``b_e^tr = F C_p⁻¹ Fᵀ`` from the current ``F`` alone, the reference keeps ``b_e`` and updates it by
the increment ``ΔF = F_{n+1} F_n⁻¹`` — the same map, so the two agree to round-off along any path,
in every dimension's embedding, for J2 and Drucker–Prager; and the pass leaves elastic rows and
their stress alone."""
import math
from types import SimpleNamespace

import numpy as np
import pytest

from parmpm.materials.plasticity.drucker_prager import dp_update
from parmpm.materials.plasticity.near_identity import RHO_MAX
from parmpm.materials.plasticity.j2 import j2_update
from parmpm.materials.plasticity.state import STATE_EPSP, STATE_WORK, initial_state, unpack
from parmpm.materials.plasticity.table import (PCOL_A, PCOL_B, PCOL_C2, PCOL_COHESION, PCOL_ETA,
                                               PCOL_ETA_2, PCOL_ETA_BAR, PCOL_G, PCOL_I0, PCOL_K, PCOL_PT, PCOL_XI,
                                               plastic_table)
from parmpm.materials.plasticity.update import plastic_energy_sums, plastic_pass

NONE = dict(hardening_exponent=None, strength_coefficient=None, rate_coefficient=None,
            reference_rate=None, friction_angle=None, dilatancy_angle=None, cohesion=None,
            matching=None, tension_cutoff=None, yield_stress=None, hardening=None,
            hardening_modulus=None, volume_correction=False, friction_angle_2=None)
J2 = SimpleNamespace(**{**NONE, "model": "j2", "youngs_modulus": 117e9, "poisson_ratio": 0.35,
                        "density": 8930.0, "yield_stress": 4e8, "hardening": "linear",
                        "hardening_modulus": 1e8})
#: elastic strains past the series' reach (:data:`RHO_MAX`): the pass's eigen path as well
J2_SOFT = SimpleNamespace(**{**vars(J2), "youngs_modulus": 2e6, "yield_stress": 3e5,
                             "hardening_modulus": 1e5})
DP = SimpleNamespace(**{**NONE, "model": "drucker_prager", "youngs_modulus": 5e7,
                        "poisson_ratio": 0.3, "density": 1800.0, "friction_angle": 30.0,
                        "dilatancy_angle": 10.0, "cohesion": 1e4})
ELASTIC = SimpleNamespace(**{**NONE, "model": "neo_hookean", "youngs_modulus": 1e6,
                             "poisson_ratio": 0.3, "density": 1000.0})


def _reference(model, table, d, path, dt):
    """``b_e`` updated by increments: (Cauchy stress, ε̄p, W_p) at the end of ``path``, and the
    largest and smallest ``‖b_e^tr − I‖_F`` along it."""
    p = table[0]
    be, epsp, work = np.eye(3), 0.0, 0.0
    tau, M, V = np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3))
    w, e, t = np.zeros(3), np.zeros(3), np.zeros(3)
    F_old = np.eye(3)
    reach = []
    for Fd in path:
        F3 = np.eye(3)
        F3[:d, :d] = Fd
        dF = F3 @ np.linalg.inv(F_old)
        F_old = F3
        reach.append(np.linalg.norm(dF @ be @ dF.T - np.eye(3)))
        if model.startswith("j2"):
            epsp, dw = j2_update(dF, be, epsp, p[PCOL_K], p[PCOL_G], 0, p[PCOL_A], p[PCOL_B], 1.0,
                                 0.0, 1.0, dt, tau, M, V, w, t)
        else:
            dl, dw = dp_update(dF, be, p[PCOL_K], p[PCOL_G], p[PCOL_ETA], p[PCOL_XI],
                               p[PCOL_ETA_BAR], p[PCOL_COHESION], p[PCOL_PT], p[PCOL_ETA_2],
                               p[PCOL_I0], 0.0, tau, M, V, w, e, t)
            epsp += dl
        work += dw
    return tau[:d, :d] / np.linalg.det(F_old), epsp, work, be, max(reach), min(reach)


MODELS = {"j2": J2, "j2_soft": J2_SOFT, "drucker_prager": DP}


@pytest.mark.parametrize("model", list(MODELS))
@pytest.mark.parametrize("d", [1, 2, 3])
def test_pass_is_the_incremental_return_map(model, d):
    """J2 metals and this Drucker–Prager sand take the pass's series path throughout, the soft
    J2 material both paths (the reach of its trial ``b_e`` crosses :data:`RHO_MAX`); the wave
    speed is exact on the eigen path and an upper bound within 1 % on the series."""
    rng = np.random.default_rng(7 + d)
    table = plastic_table({"m": MODELS[model]}, ["m"])
    F = np.eye(d)[None].copy()
    path = []
    state, stress = initial_state(1), np.zeros((1, d, d))
    mat, v = np.zeros(1, np.int64), np.zeros((1, d))
    scale = 2e-2 if model == "j2_soft" else 2e-3
    for _ in range(150):
        F[0] = (np.eye(d) + scale * rng.normal(size=(d, d))) @ F[0]
        path.append(F[0].copy())
        c = plastic_pass(d, F, mat, table, state, stress, v, 1e-6)
    sig, epsp, work, be, far, near = _reference(model, table, d, path, 1e-6)
    if model in ("j2", "drucker_prager"):
        assert far < RHO_MAX
    elif model == "j2_soft":
        assert near < RHO_MAX < far
    exact = np.sqrt(table[0, PCOL_C2] * max(1.0, np.linalg.eigvalsh(be).max()))
    if far < RHO_MAX:
        assert exact <= c <= 1.01 * exact
    else:
        assert c == pytest.approx(exact, rel=1e-12)
    assert epsp > 1e-3  # the path yields
    np.testing.assert_allclose(stress[0], sig, rtol=0, atol=1e-10 * np.abs(sig).max())
    assert state[0, STATE_EPSP] == pytest.approx(epsp, rel=1e-10)
    assert state[0, STATE_WORK] == pytest.approx(work, rel=1e-9)


def test_elastic_rows_are_left_alone_and_sums_count_plastic_rows_only():
    """Rows of an elastic material (code 0) keep their stress and state; the energy sums skip
    them; a virgin plastic row at F = I has no stress and no energy."""
    table = plastic_table({"a": ELASTIC, "b": J2}, ["a", "b"])
    d, n = 2, 4
    F = np.tile(np.eye(d), (n, 1, 1))
    F[0] = [[1.1, 0.0], [0.0, 1.0]]
    mat = np.array([0, 1, 0, 1])
    state, stress = initial_state(n), np.full((n, d, d), 7.0)
    c = plastic_pass(d, F, mat, table, state, stress, np.zeros((n, d)), 1e-6)
    assert np.all(stress[[0, 2]] == 7.0) and np.all(stress[[1, 3]] == 0.0)
    np.testing.assert_array_equal(unpack(state), np.tile(np.eye(3), (n, 1, 1)))
    assert c == pytest.approx(np.sqrt(table[1, 3]))  # c0 at b_e = I
    sums = plastic_energy_sums(d, np.array([0, n]), np.arange(n, dtype=np.uint64), np.ones(n), F,
                               mat, table, state)
    np.testing.assert_array_equal(sums, [[0.0, 0.0]])


SAND = SimpleNamespace(**{**vars(DP), "cohesion": 0.0, "dilatancy_angle": 0.0})


def _dp_path(kind, d, steps=60):
    """Deformation gradients of a path whose Drucker–Prager regions are known: ``expand``
    (isotropic stretch: the trial state passes the apex), ``shear`` (isochoric simple shear:
    onto the cone), ``squeeze`` (compression, then shear along the cone at p < 0)."""
    out = []
    for k in range(1, steps + 1):
        t = k / steps
        F = np.eye(d)
        if kind == "expand":
            F *= 1.0 + 0.02 * t
        elif kind == "shear":
            F[0, 1] = 0.05 * t
        else:
            F *= 1.0 - 0.01 * min(2 * t, 1.0)
            F[0, 1] = 0.04 * max(2 * t - 1.0, 0.0)
        out.append(F)
    return out


@pytest.mark.parametrize("material", ["cohesive", "sand"])
@pytest.mark.parametrize("kind", ["expand", "shear", "squeeze"])
@pytest.mark.parametrize("d", [2, 3])
def test_drucker_prager_regions_on_the_series_path(material, kind, d):
    """Every Drucker–Prager region (cone, apex; cohesive and cohesionless) through the pass's
    series path against the increment-driven principal-axis return with a Jacobi solver."""
    table = plastic_table({"m": DP if material == "cohesive" else SAND}, ["m"])
    path = _dp_path(kind, d)
    F = np.eye(d)[None].copy()
    state, stress = initial_state(1), np.zeros((1, d, d))
    mat, v = np.zeros(1, np.int64), np.zeros((1, d))
    for Fd in path:
        F[0] = Fd
        plastic_pass(d, F, mat, table, state, stress, v, 1e-6)
    sig, epsp, work, be, far, near = _reference("drucker_prager", table, d, path, 1e-6)
    assert far < RHO_MAX
    # a log strain is known to ~1e-15 (sums of order-1 entries of b_e): its stress to K·1e-15,
    # which is all there is at the cohesionless apex (σ = 0)
    floor = 1e-12 * table[0, PCOL_K]
    np.testing.assert_allclose(stress[0], sig, rtol=0, atol=1e-9 * np.abs(sig).max() + floor)
    assert state[0, STATE_EPSP] == pytest.approx(epsp, rel=1e-9, abs=1e-14)
    assert state[0, STATE_WORK] == pytest.approx(work, rel=1e-8, abs=floor * 1e-2)
    if kind == "expand":  # at the apex: τ = p_t I (cohesionless: no stress at all)
        J = np.linalg.det(path[-1])
        np.testing.assert_allclose(stress[0], table[0, PCOL_PT] / J * np.eye(d), rtol=1e-12,
                                   atol=floor)
    elif kind == "shear":
        assert epsp > 1e-3  # on the cone
    np.testing.assert_allclose(unpack(state)[0], np.linalg.inv(_embed3(Fd)) @ be
                               @ np.linalg.inv(_embed3(Fd)).T, rtol=0, atol=1e-12)


def _embed3(Fd):
    F3 = np.eye(3)
    F3[:Fd.shape[0], :Fd.shape[1]] = Fd
    return F3


@pytest.mark.parametrize("bad", ["nan", "inverted"])
def test_a_broken_row_stops_the_run_and_leaves_the_others(bad):
    """A NaN ``F`` (the eigen path: the series' range test is false for NaN) or an inverted one
    (``b_e = I``, the series path, ``det F < 0``) makes the pass's speed ``inf`` — the step's
    stop — and its own stress non-finite or as computed, while the rows around it, across a
    block boundary (64 rows), get the stress of a row alone."""
    table = plastic_table({"b": J2}, ["b"])
    d, n = 3, 130
    F = np.tile(np.diag([1.001, 1.0, 1.0]), (n, 1, 1))
    F[70] = np.nan if bad == "nan" else np.diag([-1.0, 1.0, 1.0])
    mat = np.zeros(n, np.int64)
    state, stress = initial_state(n), np.zeros((n, d, d))
    c = plastic_pass(d, F, mat, table, state, stress, np.zeros((n, d)), 1e-6)
    assert c == math.inf
    one_state, one = initial_state(1), np.zeros((1, d, d))
    plastic_pass(d, F[:1], mat[:1], table, one_state, one, np.zeros((1, d)), 1e-6)
    ok = np.arange(n) != 70
    np.testing.assert_array_equal(stress[ok], np.broadcast_to(one, (n - 1, d, d)))
    if bad == "nan":
        assert np.isnan(stress[70]).all()


def test_no_plastic_material_no_table():
    assert plastic_table({"a": ELASTIC}, ["a"]) is None


@pytest.mark.parametrize("d", [1, 2, 3])
def test_trial_be_is_the_congruence_bit_for_bit(d):
    """The blocked loop's scalar ``b_e^tr − I`` and the eigen path's array congruence are the same
    products in the same order, so a row gives one trial tensor whichever path reads it."""
    from numba import njit

    from parmpm.materials.plasticity.update import _congruence, _embed, _unpack, trial_be

    @njit(cache=False)
    def both(Fi, s):
        F3, C, M, T = np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3)), np.empty((3, 3))
        _embed(d, Fi, F3)
        _unpack(s, C)
        _congruence(F3, C, M, T)
        return trial_be(d, Fi, s), M

    rng = np.random.default_rng(11 + d)
    for _ in range(50):
        Fi = np.eye(d) + 0.3 * rng.normal(size=(d, d))
        A = rng.normal(size=(3, 3))
        s = np.zeros(8)
        C = np.eye(3) + 0.1 * (A @ A.T)
        for q, (r, c) in enumerate([(0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2)]):
            s[q] = C[r, c]
        x, M = both(Fi, s)
        assert x[:6] == (M[0, 0] - 1.0, M[1, 1] - 1.0, M[2, 2] - 1.0, M[0, 1], M[0, 2], M[1, 2])
        assert x[6] == pytest.approx(np.sum((M - np.eye(3)) ** 2), rel=1e-14)
