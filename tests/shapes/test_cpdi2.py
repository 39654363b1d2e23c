"""CPDI2 as an interpolator (``method.interpolator = "cpdi2"``): the tracked corners in a run.

The weights themselves are tested in ``tests/shapes/test_cpdi2_shape.py``; here the run around them:

1. a homogeneous deformation (a free, stress-free block given a uniform velocity gradient): the
   tracked corners stay CPDI1's ``F·R0·s_α`` — to round-off for an axis-aligned stretch in
   1D/2D/3D and for any gradient in 1D; under shear and spin the grid velocity (nodal mass
   averages) is not exactly affine, and the two drift apart at second order;
2. the hanging bar runs in 1D/2D/3D and holds (1D: CPDI1's result to round-off);
3. a support past the ghost layer (``lcr = "none"`` and a huge stretch) and an inverted domain
   stop the run with one line naming the particle;
4. seeding, the capped corners the snapshots draw, and a frozen particle's corners;
5. a checkpoint round trip is bit for bit, corners included.
"""
import math

import numpy as np
import pytest

from parmpm.output.domains import capped_corners, domain_corners, domain_sizes
from parmpm.core.errors import SimulationError
from parmpm.scene.load import load_scene, scene_from_toml
from parmpm.shapes import CPDI, CPDI2
from parmpm.shapes.cpdi2 import affine_corners, corner_signs
from parmpm.driver.simulation import Simulation

QUIET = ["output.snapshots=false", "output.figure=false"]
#: a velocity gradient with stretch, shear and spin (1/s)
L_GENERAL = np.array([[0.3, 0.5, -0.2], [-0.4, 0.1, 0.3], [0.2, -0.1, -0.2]])


@pytest.fixture(autouse=True)
def _in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


def block_scene(d, L, steps=5, lcr="none", E=1.0e-6, dt=1.0e-3, x_cells=16):
    """A free 0.6-m block on a 0.1-m grid (``x_cells`` cells along x, about the block's centre),
    ``ppc = 2``, given ``v = L (x − centre)``, no gravity; ``E`` tiny and ``dt`` fixed: the
    stresses do not disturb the homogeneous motion."""
    L = np.asarray(L, float)[:d, :d].tolist()
    origin = [0.3 - 0.05 * x_cells] + [-0.5] * (d - 1)
    cells = [x_cells] + [16] * (d - 1)
    return scene_from_toml(f"""
name = "block"
dim = {d}
[grid]
origin = {origin}
cell_size = 0.1
cells = {cells}
[materials.m]
model = "neo_hookean"
density = 1000.0
youngs_modulus = {E}
poisson_ratio = 0.3
[[bodies]]
shape = "box"
min = {[0.0] * d}
max = {[0.6] * d}
material = "m"
ppc = 2
velocity_gradient = {L}
[method]
interpolator = "cpdi2"
lcr = "{lcr}"
[time]
steps = {steps}
dt_max = {dt}
[output]
snapshots = false
figure = false
[metrics]
kind = "none"
""")


def _run(scene, tmp_path, name="run"):
    sim = Simulation(scene, out_dir=tmp_path / name, quiet=True)
    sim.run()
    return sim


def _mismatch(P):
    """Largest ``|c_α − F·R0·s_α|`` over the particles, relative to the longest corner."""
    ref = affine_corners(P.F, P.r0)
    return np.abs(P.corners - ref).max() / np.abs(ref).max()


# --- 1. homogeneous deformation --------------------------------------------------------------------
@pytest.mark.parametrize("d", [1, 2, 3])
def test_corners_follow_F_under_an_axis_aligned_stretch(d, tmp_path):
    sim = _run(block_scene(d, np.diag(np.diag(L_GENERAL))), tmp_path)
    P = sim.particles
    assert np.abs(P.F - np.eye(d)).max() > 1e-3  # it did deform
    assert _mismatch(P) < 1e-10


def test_corners_follow_F_for_any_gradient_in_1d(tmp_path):
    """1D: two corners, whose relative velocity is exactly ``L_p·(c_1 − c_0)``."""
    P = _run(block_scene(1, [[-0.7]]), tmp_path).particles
    assert _mismatch(P) < 1e-10


@pytest.mark.parametrize("d", [2, 3])
def test_corners_stay_near_F_under_shear_and_spin(d, tmp_path):
    """The corners see the grid velocity, which is not exactly affine once the lattice is off the
    nodes; the difference from ``F·R0`` is of second order (measured 5e-7 / 1.1e-6 relative, at
    ``|F − I|`` of 2.5e-3)."""
    P = _run(block_scene(d, L_GENERAL), tmp_path).particles
    assert np.abs(P.F - np.eye(d)).max() > 2e-3
    assert _mismatch(P) < 5e-6


# --- 2. the hanging bar ---------------------------------------------------------------------------
@pytest.mark.parametrize("scene, extra", [
    ("hanging_bar_1d", []),
    ("hanging_bar", ["time.steps=80"]),
    ("hanging_bar_3d", ["bodies.0.ppc=2", "time.steps=8"]),
])
def test_hanging_bar_runs_with_cpdi2(scene, extra, tmp_path):
    over = QUIET + extra
    two = _run(load_scene(scene, over + ["method.interpolator=cpdi2"]), tmp_path, "two")
    one = _run(load_scene(scene, over + ["method.interpolator=cpdi"]), tmp_path, "one")
    m2, m1 = two.summary["metrics"], one.summary["metrics"]
    assert not m2["separated"] and two.nstep == one.nstep
    assert two.state.update == "usl" and two.state.lcr == pytest.approx(2 * two.state.scene.min_dx)  # as cpdi's
    tol = 1e-12 if scene == "hanging_bar_1d" else 2e-3  # 1D: CPDI1 exactly (to round-off)
    assert m2["tip_displacement"] == pytest.approx(m1["tip_displacement"], rel=tol)


def test_musl_keeps_the_remap_consistent(tmp_path):
    """Found by the update-order study: moving the corners in MUSL's motion pass made the momentum
    re-map scatter with other weights than the mass (F reached 10³ in 3 steps, at any CFL). The
    corners now move in the deformation pass; the bar matches cpdi's MUSL run early on."""
    over = QUIET + ["method.update=musl", "time.steps=60"]
    two = _run(load_scene("hanging_bar", over + ["method.interpolator=cpdi2"]), tmp_path, "two")
    one = _run(load_scene("hanging_bar", over + ["method.interpolator=cpdi"]), tmp_path, "one")
    P = two.particles
    assert np.all(np.isfinite(P.F)) and np.abs(P.F).max() < 3.0
    assert two.summary["metrics"]["tip_displacement"] == pytest.approx(
        one.summary["metrics"]["tip_displacement"], rel=2e-3)


# --- 3. errors ------------------------------------------------------------------------------------
def test_reach_past_the_ghost_layer_is_one_line(tmp_path):
    """No cap and a tenfold stretch: the corners outgrow the 2-cell ghost layer (on a grid long
    enough for the stretched block)."""
    scene = block_scene(2, [[20.0, 0.0], [0.0, 0.0]], steps=400, lcr="none", x_cells=120)
    with pytest.raises(SimulationError) as exc:
        _run(scene, tmp_path)
    text = str(exc.value)
    assert "\n" not in text and "reaches beyond the ghost layer" in text, text
    assert "method.lcr" in text


def test_an_inverted_domain_stops_the_run_naming_the_particle(tmp_path):
    sim = Simulation(block_scene(2, np.zeros((2, 2))), out_dir=tmp_path / "inv", quiet=True)
    P = sim.particles
    i = int(np.flatnonzero(P.gid == 7)[0])
    P.corners[i] = P.corners[i][[1, 0, 3, 2]]  # mirrored in x: wound clockwise
    with pytest.raises(SimulationError) as exc:
        sim.run()
    text = str(exc.value)
    assert "\n" not in text and text.startswith("domain of particle 7 at ") and "inverted" in text


# --- 4. seeding, pictures, freeze -----------------------------------------------------------------
@pytest.mark.parametrize("d", [1, 2, 3])
def test_seeded_corners_are_the_domain_R0(d):
    from decomposition import SerialComm
    from parmpm.driver.set_up import set_up

    s = set_up(block_scene(d, np.zeros((d, d))), SerialComm())
    P = s.particles
    assert P.corners.shape == (P.n, 1 << d, d)
    np.testing.assert_array_equal(P.corners, affine_corners(P.F, P.r0))
    expect = 0.025 * corner_signs(d)  # half the particle spacing 0.05, bit order
    np.testing.assert_allclose(P.corners, np.broadcast_to(expect, P.corners.shape), rtol=1e-15)
    other = set_up(load_scene("hanging_bar_1d", QUIET), SerialComm())
    assert other.particles.corners.shape == (0, 2, 1)  # carried by cpdi2 runs only


def test_pictures_show_the_capped_tracked_corners():
    rng = np.random.default_rng(3)
    F = np.eye(2) + 0.4 * rng.standard_normal((5, 2, 2))
    F[np.linalg.det(F) < 0, :, 0] *= -1
    r0 = np.tile(np.diag([0.05, 0.05]), (5, 1, 1))
    x = rng.random((5, 2))
    c = affine_corners(F, r0)
    lh0 = np.full((5, 2), 0.05)
    for lcr in (None, 0.06):  # an affine domain, capped or not: CPDI1's picture
        np.testing.assert_allclose(domain_corners(2, CPDI2, lcr, x, F, r0, lh0, c),
                                   domain_corners(2, CPDI, lcr, x, F, r0, lh0), atol=1e-15)
        np.testing.assert_allclose(domain_sizes(2, CPDI2, lcr, F, r0, lh0, c),
                                   domain_sizes(2, CPDI, lcr, F, r0, lh0), rtol=1e-13)
    capped, _ = capped_corners(2, 0.06, c)
    assert np.linalg.norm(capped, axis=2).max() <= 0.06 * (1 + 1e-15)
    with pytest.raises(ValueError, match="corners"):
        domain_sizes(2, CPDI2, None, F, r0, lh0)


def test_a_frozen_particles_corners_stop_following_the_grid(tmp_path):
    sim = Simulation(block_scene(2, L_GENERAL), out_dir=tmp_path / "f", quiet=True)
    P = sim.particles
    P.rf[P.gid == 3] = np.eye(2)  # particle 3's domain is frozen (parmpm.shapes.freeze: rf != 0)
    before = P.corners[np.argsort(P.gid)]
    sim.run()
    P = sim.particles
    after = P.corners[np.argsort(P.gid)]
    np.testing.assert_array_equal(after[3], before[3])
    assert np.abs(after[4] - before[4]).max() > 1e-6


# --- 5. checkpoint round trip ---------------------------------------------------------------------
def test_restart_is_bit_identical_corners_included(tmp_path):
    over = QUIET + ["method.interpolator=cpdi2", "time.steps=40", "checkpoint.every_steps=20"]
    a = _run(load_scene("hanging_bar", over), tmp_path, "a")
    b = Simulation.from_checkpoint(tmp_path / "a" / "checkpoint_00000020.h5",
                                   out_dir=tmp_path / "b", quiet=True)
    assert b.nstep == 20 and b.particles.corners.shape == a.particles.corners.shape
    b.run()
    assert b.nstep == a.nstep == 40
    pa, pb = a.particles, b.particles
    oa, ob = np.argsort(pa.gid), np.argsort(pb.gid)
    for name in ("x", "v", "F", "stress", "corners"):
        np.testing.assert_array_equal(getattr(pa, name)[oa], getattr(pb, name)[ob], err_msg=name)
    assert not math.isnan(float(pa.corners.sum()))


def test_damage_freezes_cpdi2_domains(tmp_path):
    """The damage model's freeze (parmpm.shapes.freeze) runs under cpdi2: domains freeze, and
    a further step leaves every frozen particle's corners as they were."""
    over = QUIET + ["method.interpolator=cpdi2", "time.steps=150",
                    "materials.bar.damage={onset=1.02, fracture=1.5, freeze=0.3}",
                    "metrics.stop_on_separation=false"]
    sim = _run(load_scene("hanging_bar", over), tmp_path)
    st, P = sim.state.stepper, sim.particles
    assert st.freezing and st.frozen > 0
    frozen = np.flatnonzero(np.any(P.rf[:, :, 0] != 0, axis=1))
    gid, before = P.gid[frozen].copy(), P.corners[frozen].copy()
    st.step(sim.state.clock.last_dt, sim.gravity(sim.t), sim.t)
    P = sim.particles
    at = np.searchsorted(P.gid, gid, sorter=np.argsort(P.gid))
    np.testing.assert_array_equal(P.corners[np.argsort(P.gid)[at]], before)


@pytest.mark.parametrize("d", [1, 2, 3])
def test_snapshots_draw_the_capped_tracked_corners(d, tmp_path):
    """The snapshots' domains block holds each particle's capped corners ``x_p + ĉ_α`` as one
    cell, of the size the corners enclose (by VTK's reader, when it is installed)."""
    from parmpm.io import load_snapshots
    from test_snapshot_readers import SCENES, VTK_CELL, vtk_sizes, vtk_steps

    over = ["method.interpolator=cpdi2", "time.steps=4", "output.every_steps=2",
            "output.figure=false"] + (["bodies.0.ppc=2"] if d == 3 else [])
    sim = _run(load_scene(SCENES[d], over), tmp_path)
    P, disc = sim.particles, sim.state.disc
    o = np.argsort(P.gid)
    x, corners = P.x[o], P.corners[o]
    capped, sizes = capped_corners(d, disc.lcr, corners)
    assert np.all(sizes > 0)
    s = load_snapshots(tmp_path / "run" / f"{SCENES[d]}.xdmf")
    drawn = domain_corners(d, CPDI2, disc.lcr, x, None, None, None, corners)
    if d < 3:  # the writer's order is domain_corners' (2D: counter-clockwise)
        np.testing.assert_array_equal(s["domains"][-1], drawn)
    around = [0, 1, 3, 2] if d == 2 else list(range(1 << d))  # 3D: box order = bit order
    np.testing.assert_array_equal(drawn, x[:, None, :] + capped[:, around])
    *_, (_, blocks) = vtk_steps(tmp_path / "run" / f"{SCENES[d]}.xdmf")
    grid = blocks["domains"]
    assert {grid.GetCellType(i) for i in range(grid.GetNumberOfCells())} == {VTK_CELL[d]}
    np.testing.assert_allclose(vtk_sizes(grid), sizes, rtol=1e-10)
