"""Manufactured-solution forcing, slip regions, spinning bodies and particle domains.

* the body force of docs/verification.md §3 makes the prescribed motion solve the neo-Hookean momentum
  equation (checked by finite differences, independently of its derivation);
* the step's numba kernel equals the numpy formula (compiled and through ``py_func``);
* a manufactured run starts exactly on the exact field;
* slip regions zero only the normal velocity, fixed regions all of it;
* ``angular_velocity`` seeds a rigid spin; domain sizes follow each interpolator's rule.
"""
import math

import numpy as np
import pytest

import parmpm
from parmpm.core.errors import SceneError
from parmpm.exact.bars import manufactured_body_force, manufactured_motion
from parmpm.grid.update import apply_regions
from parmpm.loads.manufactured import body_force
from parmpm.materials import lame
from parmpm.scene.load import scene_from_toml
from parmpm.shapes import CPDI, CPGIMP, MPM, UGIMP

A, E, NU, RHO = 0.05, 1.0e4, 0.3, 1.0
LAM, MU = lame(E, NU)
C = math.sqrt(E / RHO)


def _nominal_stress_diag(X, t, k):
    """P_kk of neo-Hookean at the exact F (diagonal): μ(F − 1/F) + λ ln J / F."""
    _, _, Fd = manufactured_motion(X, t, A, C)
    J = np.prod(Fd, axis=1)
    F = Fd[:, k]
    return MU * (F - 1.0 / F) + LAM * np.log(J) / F


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_body_force_balances_momentum(dim):
    rng = np.random.default_rng(dim)
    X = rng.uniform(0.05, 0.95, size=(40, dim))
    t = 0.0137
    b = manufactured_body_force(X, t, A, C, LAM, MU, RHO)
    e, tau = 1e-5, 1e-7
    u_p, _, _ = manufactured_motion(X, t + tau, A, C)
    u_0, _, _ = manufactured_motion(X, t, A, C)
    u_m, _, _ = manufactured_motion(X, t - tau, A, C)
    accel = (u_p - 2 * u_0 + u_m) / tau**2
    for k in range(dim):
        dX = np.zeros(dim)
        dX[k] = e
        div = (_nominal_stress_diag(X + dX, t, k) - _nominal_stress_diag(X - dX, t, k)) / (2 * e)
        residual = RHO * accel[:, k] - div - RHO * b[:, k]
        scale = np.max(np.abs(RHO * accel[:, k])) + np.max(np.abs(div))
        assert np.max(np.abs(residual)) < 2e-4 * scale


@pytest.mark.parametrize("jit", [True, False], ids=["jit", "py"])
@pytest.mark.parametrize("dim", [1, 2, 3])
def test_body_force_kernel_matches_formula(dim, jit):
    X = np.random.default_rng(7).uniform(0, 1, size=(25, dim))
    out = np.zeros((25, dim))
    (body_force if jit else body_force.py_func)(dim, X, 0.004, A, C, LAM, MU, RHO, out)
    np.testing.assert_allclose(out, manufactured_body_force(X, 0.004, A, C, LAM, MU, RHO),
                               rtol=1e-12, atol=1e-12 * np.abs(out).max())


def test_manufactured_run_starts_on_the_exact_field(tmp_path):
    scene = parmpm.load_scene("manufactured", ["time.steps=1", "output.figure=false"])
    sim = parmpm.Simulation(scene, tmp_path, quiet=True)
    P = sim.particles
    u, v, Fd = manufactured_motion(P.x0, 0.0, A, C)
    np.testing.assert_array_equal(P.x, P.x0 + u)
    np.testing.assert_array_equal(P.v, v)
    np.testing.assert_array_equal(P.F[:, 0, 0], Fd[:, 0])
    np.testing.assert_array_equal(P.F[:, 1, 1], Fd[:, 1])
    assert np.all(P.F[:, 0, 1] == 0) and np.abs(P.stress).max() > 0
    summary = sim.run()
    m = summary["metrics"]
    assert m["samples"] == 2 and 0 < m["rms_error"] < 1e-4  # one step off the exact field


def test_manufactured_needs_one_neo_hookean_material():
    text = parmpm.load_scene("manufactured").to_toml().replace('"neo_hookean"', '"linear_elastic"')
    with pytest.raises(SceneError, match='manufactured.*"neo_hookean"'):
        scene_from_toml(text)


@pytest.mark.parametrize("jit", [True, False], ids=["jit", "py"])
def test_slip_and_fixed_regions(jit):
    apply = apply_regions if jit else apply_regions.py_func
    origin, h = np.zeros(3), np.ones(3)
    regions = np.array([[[0, 0, 0], [1, 5, 0]], [[4, 0, 0], [5, 5, 0]]], float)
    normal = np.array([0, -1])  # slip with normal x on x <= 1; fixed on x >= 4
    for node, expect in (((1, 2, 0), [0.0, 2.0]), ((2, 2, 0), [1.0, 2.0]), ((4, 1, 0), [0.0, 0.0])):
        vel = np.array([1.0, 2.0, 0.0])
        apply(2, np.array(node), origin, h, regions, normal, vel)
        assert list(vel[:2]) == expect


def test_slip_region_scene_errors():
    base = parmpm.load_scene("hanging_bar").to_toml()
    with pytest.raises(SceneError, match=r'boundary\.slip_regions\.0\.normal: expected one of "x", "y", got "z"'):
        scene_from_toml(base.replace('normal = "y"', 'normal = "z"', 1))


def test_angular_velocity_seeds_a_rigid_spin(tmp_path):
    scene = parmpm.load_scene("spinning_disk", ["time.steps=1"])
    sim = parmpm.Simulation(scene, tmp_path, quiet=True)
    P = sim.particles
    w = scene.data["bodies"][0]["angular_velocity"]
    np.testing.assert_allclose(P.v, w * np.stack([-P.x[:, 1], P.x[:, 0]], axis=1), rtol=0, atol=1e-14)
    text = parmpm.load_scene("hanging_bar_1d").to_toml().replace('material = "bar"',
                                                                  'material = "bar"\nangular_velocity = 1.0')
    with pytest.raises(SceneError, match="angular_velocity.*1D"):
        scene_from_toml(text)


def test_domain_sizes_under_rotation():
    th = 0.5 * math.pi * np.array([0.0, 0.5, 1.0])
    F = np.stack([[[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]] for a in th])
    lh0 = np.full((3, 2), 0.25)
    r0 = np.stack([np.diag(lh0[i]) for i in range(3)])
    sizes = {m: parmpm.domain_sizes(2, m, None, F, r0, lh0) for m in (MPM, UGIMP, CPGIMP, CPDI)}
    np.testing.assert_allclose(sizes[CPDI], 0.25, rtol=1e-14)        # rotates rigidly
    np.testing.assert_allclose(sizes[UGIMP], 0.25, rtol=1e-14)       # fixed
    np.testing.assert_allclose(sizes[CPGIMP], 0.25 * np.cos(th) ** 2, atol=1e-16)  # collapses
    corners = parmpm.domain_corners(2, CPDI, None, np.zeros((3, 2)), F, r0, lh0)
    assert corners.shape == (3, 4, 2)
    np.testing.assert_allclose(corners[2, 0], [0.25, -0.25], atol=1e-15)  # (-1,-1) corner turned 90°
    np.testing.assert_allclose(parmpm.domain_sizes(2, CPDI, 0.1, F, 2 * r0, 2 * lh0),
                               2 * 0.1**2, rtol=1e-12)  # capped: a square of half-diagonal l_cr


def test_manufactured_restart_is_bit_identical(tmp_path):
    """The forcing is re-attached on restart (particles are not re-initialised)."""
    over = ["time.steps=30", "checkpoint.every_steps=15", "output.figure=false"]
    a = parmpm.Simulation(parmpm.load_scene("manufactured", over), tmp_path / "a", quiet=True)
    full = a.run()
    b = parmpm.Simulation.from_checkpoint(tmp_path / "a" / "checkpoint_00000015.h5",
                                          out_dir=tmp_path / "b", quiet=True)
    again = b.run()
    assert again["metrics"] == full["metrics"] and again["final"] == full["final"]
    order_a, order_b = np.argsort(a.particles.gid), np.argsort(b.particles.gid)
    np.testing.assert_array_equal(a.particles.x[order_a], b.particles.x[order_b])


def test_only_separation_metrics_count_pieces_and_stop_on_separation():
    from parmpm.output.metrics import METRICS

    assert {k for k, cls in METRICS.items() if cls.needs_components} == {"hanging_bar",
                                                                          "tension_bar"}
    with pytest.raises(SceneError, match='metrics.stop_on_separation: only the "hanging_bar" and '
                                         '"tension_bar" metrics track separation'):
        parmpm.load_scene("manufactured", ["metrics.stop_on_separation=true"])
