"""Seeding (:mod:`parmpm.seeding`): bodies made block by block (a box's lattice kept axis by
axis, a turned box turned block by block, a disk or sphere masked block by block) give the same
points, bit for bit, the same particles per patch and the same members of a rank's patches as
seeding every particle at once and locating each one — what lets set-up skip holding every
position."""
from __future__ import annotations

import numpy as np
import pytest

from parmpm import Simulation, load_scene
from parmpm.materials import material_table
from parmpm.particles import locate_patches
from parmpm import seeding
from parmpm.seeding import _Ball, _Lattice, _lattice, _turn, _Turned, seed_bodies


def test_lattice_points_are_the_meshgrid_points():
    lo, h, n = np.array([0.1, -0.3, 0.2]), np.array([0.05, 0.025, 0.1]), [7, 5, 3]
    lat = _Lattice(lo, h, n)
    full = _lattice(lo, lo + np.array(n) * h, h)
    assert np.array_equal(lat.full(), full)
    ids = np.array([0, 6, 7, 34, 104])
    assert np.array_equal(lat[ids], full[ids])


CASES = [
    ("tension_bar", ["metrics.kind=none", "grid.patch_size=[5, 3]", "grid.origin=[-0.6013, -0.1071]"]),
    ("hanging_bar_3d", ["metrics.kind=none", "grid.patch_size=3"]),
    ("hanging_bar_1d", ["metrics.kind=none", "grid.patch_size=4"]),
    ("tension_bar", ["bodies.2.angle=10.0", "bodies.0.angle=-3.0", "grid.patch_size=[5, 3]"]),
    ("spinning_disk", ["grid.patch_size=5"]),
    ("hanging_bar_3d", ["bodies.0={shape='sphere', center=[0.5, -0.5, 0.5], radius=0.45, "
                        "material='bar', ppc=3}", "grid.patch_size=3"]),
    ("manufactured", ["grid.patch_size=3"]),
]


@pytest.mark.parametrize("block", [seeding.BLOCK, 32])
@pytest.mark.parametrize("scene, over", CASES)
def test_counts_and_members_match_locating_every_particle(scene, over, block, tmp_path,
                                                         monkeypatch):
    monkeypatch.setattr(seeding, "BLOCK", block)
    sc = load_scene(scene, over)
    sim = Simulation(sc, tmp_path, quiet=True)  # for its discretisation
    D, lay = sim.disc, sim.disc.layout
    _, names = material_table(sc.data["materials"])
    seeds = seed_bodies(sc.data, {n: i for i, n in enumerate(names)})
    x = seeds.x
    if sc.data.get("manufactured"):  # the particles start displaced: found where they start
        seeds.motion = lambda X: X + 0.01 * np.sin(7.0 * X)
        x = seeds.motion(x)
    where = np.zeros(len(x), np.int64)
    bad, _ = locate_patches(sc.dim, x, D.origin3, D.inv_h3, lay.cells3, lay.psize3,
                            lay.patches_per_axis, where, where)
    assert bad < 0
    counts = seeds.patch_counts(D)
    assert np.array_equal(counts, np.bincount(where, minlength=lay.n_patches))
    owned = np.random.default_rng(1).random(lay.n_patches) < 0.4
    mine = seeds.members(D, owned)
    assert np.array_equal(mine, np.flatnonzero(owned[where]))
    params, _ = material_table(sc.data["materials"])
    np.testing.assert_array_equal(seeds.particles(params, mine).x0, seeds.x[mine])


@pytest.mark.parametrize("block", [16, 48, 4096])
@pytest.mark.parametrize("d, count", [(2, (37, 23)), (2, (64, 1)), (3, (9, 7, 5)), (2, (1, 1))])
def test_turned_blocks_are_the_whole_body_turned(d, count, block, monkeypatch):
    """Turned block by block (aligned blocks, a short last one joined to the one before), every
    point has the bits of the whole body turned in one BLAS call."""
    monkeypatch.setattr(seeding, "BLOCK", block)
    lo, h = np.array([0.1, -0.3, 0.2])[:d], np.array([0.05, 0.025, 0.1])[:d]
    lat = _Lattice(lo, h, count)
    mid, turn = lo + 0.5 * np.array(count) * h, _turn(d, 23.0)
    whole = (lat.full() - mid) @ turn.T + mid
    body = _Turned(lat, mid, turn)
    assert np.array_equal(body.points(np.arange(lat.n)), whole)
    ids = np.sort(np.random.default_rng(2).choice(lat.n, lat.n // 3 + 1, replace=False))
    assert np.array_equal(body.points(ids), whole[ids])


@pytest.mark.parametrize("block", [32, 4096])
def test_ball_is_its_box_lattice_masked(block, monkeypatch):
    monkeypatch.setattr(seeding, "BLOCK", block)
    for d in (2, 3):
        lo, h, n = np.full(d, -0.61), np.full(d, 0.05), [27, 25, 24][:d]
        c, r = np.array([0.02, -0.01, 0.03])[:d], 0.55
        lat = _Lattice(lo, h, n)
        full = _lattice(lo, lo + np.array(n) * h, h)
        ball = _Ball(lat, c, r)
        expect = full[np.sum((full - c) ** 2, axis=1) <= r * r]
        assert len(ball) == expect.shape[0]
        assert np.array_equal(ball.points(np.arange(len(ball))), expect)
        ids = np.array([0, 5, len(ball) // 2, len(ball) - 1])
        assert np.array_equal(ball.points(ids), expect[ids])


def test_outside_the_grid_names_the_particle(tmp_path):
    from parmpm.errors import SimulationError

    sc = load_scene("spinning_disk", ["grid.patch_size=6"])
    D = Simulation(sc, tmp_path, quiet=True).disc
    seeds = seed_bodies(sc.data, {"disk": 0})
    seeds.motion = lambda X: X + np.where(np.arange(len(X))[:, None] == 7, 5.0, 0.0)
    with pytest.raises(SimulationError, match=r"particle 7 at \(.*\) is outside the grid"):
        seeds.patch_counts(D)
