"""The damage-triggered CPDI domain freeze (:mod:`parmpm.shapes.freeze`): a domain freezes when
its particle's damage reaches the material's ``freeze`` value, then turns with the material
(rotated rigidly by 90°, it keeps its shape relative to the material) and stops stretching;
below the threshold nothing changes; on the hanging bar, damage with freezing lets CPDI separate
where the plain model holds; the polar rotation is right in 2D and 3D."""
import math

import numpy as np
import pytest

import parmpm
from parmpm.materials import material_table
from parmpm.scene.records import Damage, Material
from parmpm.shapes.freeze import freeze_domains, polar_rotation

QUIET = ["output.snapshots=false", "output.figure=false"]


def table(freeze=0.5):
    params, _ = material_table({"m": Material("neo_hookean", 1000.0, 1e6, 0.3, Damage(
        "max_principal_stretch", 1.2, 2.0, "linear", freeze))})
    return params


def rot(d, angle, axis=2):
    c, s = math.cos(angle), math.sin(angle)
    if d == 2:
        return np.array([[c, -s], [s, c]])
    Q = np.eye(3)
    i, j = [k for k in range(3) if k != axis]
    Q[i, i], Q[i, j], Q[j, i], Q[j, j] = c, -s, s, c
    return Q


def one_particle(d, F, damage):
    F3 = np.zeros((1, 3, 3))[:, :d, :d].copy()
    F3[0] = F
    r0 = np.zeros((1, d, d))
    r0[0] = np.diag(np.full(d, 0.05)) + 0.01 * np.triu(np.ones((d, d)), 1)
    return F3, r0, np.zeros((1, d, d)), np.array([damage]), np.zeros(1, np.int64)


@pytest.mark.parametrize("jit", [True, False])
@pytest.mark.parametrize("d", [2, 3])
def test_polar_rotation(d, jit):
    rng = np.random.default_rng(d)
    f = polar_rotation if jit else polar_rotation.py_func
    for _ in range(10):
        A = rng.normal(size=(d, d))
        S = A @ A.T + d * np.eye(d)            # symmetric positive definite stretch
        Q = rot(d, rng.uniform(-3, 3), axis=int(rng.integers(3)))
        F = np.zeros((3, 3))
        F[:d, :d] = Q @ S
        out = np.zeros((3, 3))
        f(d, F, out)
        np.testing.assert_allclose(out[:d, :d], Q, atol=1e-12)


@pytest.mark.parametrize("d", [2, 3])
def test_frozen_domain_turns_with_the_material_and_stops_stretching(d):
    """Stretch to 1.9 (damage 0.875 ≥ freeze 0.5): the domain freezes at R_f = F·R0. A rigid
    90° rotation of the material turns the domain with it (R = Q·R_f); stretching the material
    further along its principal axis leaves the frozen domain as it was."""
    params = table(0.5)
    F0 = np.diag([1.9] + [1.1] * (d - 1))
    F, r0, rf, damage, mat = one_particle(d, F0, 0.875)
    R_f = F[0] @ r0[0]
    assert freeze_domains(d, F, r0, rf, damage, mat, params) == 1
    assert np.any(rf != 0)
    np.testing.assert_allclose(F[0] @ r0[0], R_f, atol=1e-14)
    Q = rot(d, math.pi / 2)
    F[0] = Q @ F0
    freeze_domains(d, F, r0, rf, damage, mat, params)
    np.testing.assert_allclose(F[0] @ r0[0], Q @ R_f, atol=1e-14)
    # keeps its shape relative to the material: same edge lengths and angle
    np.testing.assert_allclose((Q @ R_f).T @ (Q @ R_f), R_f.T @ R_f, atol=1e-14)
    F[0] = Q @ np.diag([3.0] + [1.1] * (d - 1))   # much more stretch, same rotation
    freeze_domains(d, F, r0, rf, damage, mat, params)
    np.testing.assert_allclose(F[0] @ r0[0], Q @ R_f, atol=1e-14)


def test_below_the_threshold_nothing_changes():
    params = table(0.9)
    F, r0, rf, damage, mat = one_particle(2, np.diag([1.5, 1.0]), 0.4)
    before = r0.copy()
    assert freeze_domains(2, F, r0, rf, damage, mat, params) == 0
    assert np.array_equal(r0, before) and not np.any(rf)


def test_damage_with_freeze_separates_the_hanging_bar_plain_cpdi_holds(tmp_path):
    """The seed's bar (CPDI, l_cr = 2Δx) stretches to ~4.6 near its support and holds together;
    with damage (onset 1.2, fracture 2.0) it separates, and earlier when the domains freeze at
    D = 0.5 (stretch 1.6) than with freezing off (measured 0.030 s against 0.046 s, where only
    the l_cr cap lets the strengthless, stretched material part)."""
    common = QUIET + ["time.end=0.3", "metrics.stop_on_separation=true"]
    dmg = "materials.bar.damage={onset=1.2, fracture=2.0, freeze=%s}"
    plain = parmpm.run("hanging_bar", common, out_dir=tmp_path / "plain")["metrics"]
    frozen = parmpm.run("hanging_bar", common + [dmg % "0.5"], out_dir=tmp_path / "f")["metrics"]
    never = parmpm.run("hanging_bar", common + [dmg % '"never"'], out_dir=tmp_path / "n")["metrics"]
    assert not plain["separated"] and frozen["separated"] and never["separated"]
    assert frozen["separation_time"] < 0.8 * never["separation_time"]
    assert frozen["max_stretch"] < never["max_stretch"]


def test_3d_domains_freeze_and_kernels_agree(tmp_path):
    """The 3D bar with damage freezes domains (Newton polar rotation in the loop), and the
    specialised 3D kernels give the generic kernels' state to round-off."""
    from parmpm.driver.simulation import Simulation

    over = QUIET + ["time.steps=60", "metrics.stop_on_separation=false",
                    "materials.bar.damage={onset=1.02, fracture=1.5, freeze=0.3}"]
    runs = []
    for specialised in (True, False):
        sim = Simulation(parmpm.load_scene("hanging_bar_3d", over), tmp_path / str(specialised),
                         quiet=True)
        if not specialised:
            sim.state.stepper.use_kernels("generic")
        sim.run()
        runs.append((sim.state.stepper.frozen, sim.particles))
    (nf, a), (ng, b) = runs
    assert nf == ng > 0
    np.testing.assert_allclose(a.damage, b.damage, rtol=0, atol=1e-8)
    np.testing.assert_allclose(a.x, b.x, rtol=0, atol=1e-12)
    np.testing.assert_allclose(a.r0, b.r0, rtol=0, atol=1e-14)
