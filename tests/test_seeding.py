"""Seeding (:mod:`parmpm.seeding`): a box's lattice kept axis by axis gives the same points, the
same particles per patch and the same members of a rank's patches as seeding every particle
and locating each one — what lets a run without metrics skip holding every position."""
from __future__ import annotations

import numpy as np
import pytest

from parmpm import Simulation, load_scene
from parmpm.materials import material_table
from parmpm.particles import locate_patches
from parmpm.seeding import _Lattice, _lattice, seed_bodies


def test_lattice_points_are_the_meshgrid_points():
    lo, h, n = np.array([0.1, -0.3, 0.2]), np.array([0.05, 0.025, 0.1]), [7, 5, 3]
    lat = _Lattice(lo, h, n)
    full = _lattice(lo, lo + np.array(n) * h, h)
    assert np.array_equal(lat.full(), full)
    ids = np.array([0, 6, 7, 34, 104])
    assert np.array_equal(lat[ids], full[ids])


@pytest.mark.parametrize("scene, over", [
    ("tension_bar", ["metrics.kind=none", "grid.patch_size=[5, 3]", "grid.origin=[-0.6013, -0.1071]"]),
    ("hanging_bar_3d", ["metrics.kind=none", "grid.patch_size=3"]),
    ("hanging_bar_1d", ["metrics.kind=none", "grid.patch_size=4"]),
])
def test_counts_and_members_match_locating_every_particle(scene, over, tmp_path):
    sc = load_scene(scene, over)
    sim = Simulation(sc, tmp_path, quiet=True)  # for its discretisation
    D, lay = sim.disc, sim.disc.layout
    _, names = material_table(sc.data["materials"])
    seeds = seed_bodies(sc.data, {n: i for i, n in enumerate(names)})
    x = seeds.x
    where = np.zeros(len(x), np.int64)
    bad, _ = locate_patches(sc.dim, x, D.origin3, D.inv_h3, lay.cells3, lay.psize3,
                            lay.patches_per_axis, where, where)
    assert bad < 0
    counts = seeds.patch_counts(D)
    assert np.array_equal(counts, np.bincount(where, minlength=lay.n_patches))
    owned = np.random.default_rng(1).random(lay.n_patches) < 0.4
    assert np.array_equal(seeds.members(D, owned), np.flatnonzero(owned[where]))


def test_turned_and_round_bodies_are_seeded_whole(tmp_path):
    """Patch membership of a turned box or a disk is not separable by axis: no counts."""
    for name, over in (("tension_bar", ["bodies.2.angle=10.0"]), ("spinning_disk", [])):
        sc = load_scene(name, over)
        sim = Simulation(sc, tmp_path / name, quiet=True)
        _, names = material_table(sc.data["materials"])
        assert seed_bodies(sc.data, {n: i for i, n in enumerate(names)}).patch_counts(sim.disc) is None
