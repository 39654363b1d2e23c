"""The stretch-driven damage model (:mod:`parmpm.materials.damage`): a particle under a prescribed
deformation gradient follows the softening law exactly (loading, irreversibility on unloading,
both laws, 1D/2D/3D, the specialised 2D/3D kernels' scalar forms too); the stress is degraded
as documented in tension and compression; the largest principal stretch is rotation-invariant;
a scene whose damage never starts is bit for bit the scene without the model; a damaging run
gives the same damage in the specialised and the generic kernels; bad tables are one-line
errors."""
import math

import numpy as np
import pytest

import parmpm
from parmpm.core.errors import SceneError
from parmpm.transfer.kernels2d import KERNELS_2D
from parmpm.materials import material_table
from parmpm.scene.records import Damage, Material
from parmpm.materials.damage import (damage_scalar, damage_update, degrade, degrade_2d, degrade_3d,
                                    max_stretch, max_stretch_2d, max_stretch_3d, pressure_term)
from parmpm.materials.laws import cauchy_stress
from parmpm.driver.simulation import Simulation

QUIET = ["output.snapshots=false", "output.figure=false"]


def material(softening="linear", onset=1.2, fracture=1.8, model="neo_hookean"):
    return {"m": Material(model, 1000.0, 1e6, 0.3, Damage("max_principal_stretch", onset, fracture,
                                                        softening, 0.9))}


def expected_damage(softening, lam, onset=1.2, fracture=1.8):
    if lam <= onset:
        return 0.0
    x = (lam - onset) / (fracture - onset)
    return min(1.0, x) if softening == "linear" else 1.0 - math.exp(-x)


def rotation(d, rng):
    if d == 1:
        return np.eye(1)
    q, r = np.linalg.qr(rng.normal(size=(d, d)))
    q = q @ np.diag(np.sign(np.diag(r)))
    return q if np.linalg.det(q) > 0 else q @ np.diag([-1.0] + [1.0] * (d - 1))


@pytest.mark.parametrize("jit", [True, False])
@pytest.mark.parametrize("softening", ["linear", "exponential"])
@pytest.mark.parametrize("d", [1, 2, 3])
def test_single_particle_follows_the_softening_law(d, softening, jit):
    """Uniaxial stretch along a rotated axis, up to 2.0 and back to 1.0: D = g(λ_max) on loading
    and stays at its largest value on unloading (exact, up to rounding of λ itself)."""
    update = damage_update if jit else damage_update.py_func
    params, _ = material_table(material(softening))
    rng = np.random.default_rng(d)
    Q = rotation(d, rng)
    lams = np.concatenate([np.linspace(1.0, 2.0, 21), np.linspace(1.95, 1.0, 20)])
    D, peak = 0.0, 0.0
    for lam in lams:
        U = np.eye(d)
        U[0, 0] = lam
        F3 = np.zeros((3, 3))
        F3[:d, :d] = Q @ U @ Q.T if d > 1 else U
        D = update(d, params[0], F3, D)
        peak = max(peak, lam)
        assert D == pytest.approx(expected_damage(softening, peak), abs=1e-12)
    assert D == pytest.approx(expected_damage(softening, 2.0)) and D > 0.5


def test_scalar_forms_match_the_array_forms():
    """The specialised kernels' scalar helpers (2D, 3D) give the generic kernels' numbers."""
    params, _ = material_table(material("exponential"))
    rng = np.random.default_rng(7)
    for d, scalar in ((2, max_stretch_2d), (3, max_stretch_3d)):
        for _ in range(20):
            F3 = np.zeros((3, 3))
            F3[:d, :d] = rotation(d, rng) @ np.diag(rng.uniform(0.7, 2.2, d)) @ rotation(d, rng)
            lam = scalar(*F3[:d, :d].ravel())
            assert lam == pytest.approx(np.sqrt(np.linalg.eigvalsh(F3[:d, :d] @ F3[:d, :d].T).max()),
                                        rel=1e-12)
            assert lam == pytest.approx(max_stretch(d, F3), rel=1e-14)
            D0 = rng.uniform(0, 0.3)
            assert damage_scalar(params, 0, D0, lam) == pytest.approx(
                damage_update(d, params[0], F3, D0), rel=1e-14)


@pytest.mark.parametrize("d", [1, 2, 3])
def test_degraded_stress_tension_and_compression(d):
    """σ = (1−D)σ_e + D·min(p_v, 0)·I: the law's pressure term is kept in compression only."""
    rng = np.random.default_rng(d)
    D = 0.4
    for pv in (3.0, -7.0):
        S = rng.normal(0, 1.0, (d, d))
        S = S + S.T + 10.0 * np.eye(d)  # a tensile mean stress: it is p_v that decides
        want = (1 - D) * S + D * min(pv, 0.0) * np.eye(d)
        out = np.zeros((3, 3))
        out[:d, :d] = S
        degrade(d, D, pv, out)
        np.testing.assert_allclose(out[:d, :d], want, rtol=1e-14, atol=1e-13)
        if d == 2:
            np.testing.assert_allclose(degrade_2d(D, (2.0 * pv, 2.0), S[0, 0], S[0, 1], S[1, 1]),
                                       (want[0, 0], want[0, 1], want[1, 1]), rtol=1e-14)
        if d == 3:
            np.testing.assert_allclose(
                degrade_3d(D, (pv, 1.0), S[0, 0], S[0, 1], S[0, 2], S[1, 1], S[1, 2], S[2, 2]),
                (want[0, 0], want[0, 1], want[0, 2], want[1, 1], want[1, 2], want[2, 2]), rtol=1e-14)
    out = np.eye(3)
    degrade(3, 0.0, -5.0, out)  # D = 0: untouched, bit for bit
    assert np.array_equal(out, np.eye(3))


def test_the_pressure_term_of_a_pair():
    """The scalar laws hand ``p_v`` as ``(p_n, p_d)``, divided only for a damaged particle:
    ``p_n / p_d``, or ``−∞`` where ``p_d`` is not positive (an inverted or NaN ``J``, as the
    neo-Hookean law's ``p_v`` was)."""
    assert pressure_term((-6.0, 1.5)) == -4.0 and pressure_term((3.0, 1.0)) == 3.0
    for bad in (0.0, -1.0, float("nan")):
        assert pressure_term((1.0, bad)) == -math.inf


def test_broken_particle_resists_collapse():
    """A fully damaged neo-Hookean particle sheared and squeezed to J = 0.0015 (the state that
    blew up the tension bar with ``freeze = "never"``) has a *tensile* mean elastic stress, yet it
    keeps the law's pressure ``λ ln J / J`` — and carries nothing once its volume is not reduced."""
    params, _ = material_table(material())
    lam = params[0, 4]
    F = np.eye(3)
    F[:2, :2] = [[3.01928008, 3.45767633], [3.05052982, 3.49394864]]
    J = np.linalg.det(F[:2, :2])
    el, dm = np.zeros((3, 3)), np.zeros((3, 3))
    cauchy_stress(2, params[0], F, 0.0, el)
    cauchy_stress(2, params[0], F, 1.0, dm)
    assert 0 < J < 0.002 and np.trace(el[:2, :2]) > 0
    np.testing.assert_allclose(dm[:2, :2], lam * np.log(J) / J * np.eye(2), rtol=1e-12)
    for f in (np.diag([1.5, 1.0, 1.0]), np.array([[1.0, 0.7, 0.0], [0.0, 1.0, 0.0], [0, 0, 1.0]])):
        cauchy_stress(2, params[0], f, 1.0, dm)  # J >= 1: a broken particle carries nothing
        assert np.all(dm[:2, :2] == 0.0)


def test_cauchy_stress_is_degraded_by_the_damage():
    params, _ = material_table(material())
    F = np.diag([1.5, 1.0, 1.0])
    el, dm = np.zeros((3, 3)), np.zeros((3, 3))
    cauchy_stress(2, params[0], F, 0.0, el)
    cauchy_stress(2, params[0], F, 0.25, dm)
    assert np.trace(el[:2, :2]) > 0
    np.testing.assert_allclose(dm[:2, :2], 0.75 * el[:2, :2], rtol=1e-15)


DAMAGE_OFF = ["materials.bar.damage={onset=50.0, fracture=60.0}"]  # never reached


@pytest.mark.parametrize("scene,method", [("hanging_bar", "cpdi"), ("hanging_bar", "mpm"),
                                          ("hanging_bar_1d", "cpdi"), ("hanging_bar_3d", "cpdi")])
def test_undamaged_run_is_bit_identical_to_no_damage_model(scene, method, tmp_path):
    runs = []
    for extra in ([], DAMAGE_OFF):
        sc = parmpm.load_scene(scene, QUIET + [f'method.interpolator="{method}"', "time.steps=30"]
                               + extra)
        sim = Simulation(sc, tmp_path / str(len(runs)), quiet=True)
        sim.run()
        runs.append(sim.particles)
    a, b = runs
    for name in ("x", "v", "F", "stress", "damage"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert not np.any(b.damage)


@pytest.mark.parametrize("softening", ["linear", "exponential"])
def test_damaging_run_specialised_equals_generic(softening, tmp_path):
    """The 2D hanging bar with onset 1.05: damage grows, and the specialised 2D kernels give the
    generic kernels' damage and stress (to round-off) step after step."""
    over = QUIET + ["time.steps=60", f'materials.bar.damage={{onset=1.05, fracture=1.6, '
                                     f'softening="{softening}"}}']
    results = []
    for specialised in (True, False):
        sim = Simulation(parmpm.load_scene("hanging_bar", over), tmp_path / str(specialised),
                         quiet=True)
        if not specialised:
            sim.state.stepper.use_kernels("generic")
        else:
            assert tuple(sim.state.stepper.transfers.kernels) == KERNELS_2D[sim.state.stepper.disc.method]
        sim.run()
        results.append(sim.particles)
    fast, gen = results
    assert fast.damage.max() > 0.01
    np.testing.assert_allclose(fast.damage, gen.damage, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fast.stress, gen.stress, rtol=0, atol=1e-6 * np.abs(gen.stress).max())


def test_damage_softens_the_bar(tmp_path):
    """With damage the hanging bar's tip falls further than without (it is softer; domain
    freezing off, so that the bar does not separate and stop the run first)."""
    tips = []
    for extra in ([], ['materials.bar.damage={onset=1.02, fracture=1.5, freeze="never"}']):
        r = parmpm.run("hanging_bar", QUIET + ["time.end=0.05"] + extra, out_dir=tmp_path / str(len(tips)))
        tips.append(r["metrics"]["tip_displacement"])
    assert tips[1] < tips[0] < 0


@pytest.mark.parametrize("table,message", [
    ("{onset=1.5, fracture=1.2}", "fracture: expected a stretch > onset (1.5)"),
    ("{onset=0.9, fracture=1.2}", "onset: expected a stretch >= 1"),
    ("{fracture=1.2}", "onset: required key is missing"),
    ("{onset=1.1, fracture=1.2, softening=\"cubic\"}", "softening: expected one of"),
    ("{onset=1.1, fracture=1.2, freeze=0.0}", "freeze: expected a damage"),
    ("{onset=1.1, fracture=1.2, freeze=\"always\"}", "freeze: expected a damage"),
    ("{onset=1.1, fracture=1.2, onsett=1}", "unknown key 'materials.bar.damage.onsett'"),
])
def test_bad_damage_tables_are_one_line_errors(table, message):
    with pytest.raises(SceneError, match=message.replace("(", r"\(").replace(")", r"\)")) as err:
        parmpm.load_scene("hanging_bar", [f"materials.bar.damage={table}"])
    assert "\n" not in str(err.value)
