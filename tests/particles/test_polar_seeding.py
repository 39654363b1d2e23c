"""A disk seeded "conforming" (:mod:`parmpm.particles.seeding.polar`): rings whose outer particles
follow the circle, each cell's exact area as its volume, against independent quadrature and
against the lattice seeding it replaces as the default."""
from __future__ import annotations

import math

import numpy as np
import pytest

from parmpm import load_scene
from parmpm.core.errors import SceneError
from parmpm.materials import material_table
from parmpm.particles import seeding
from parmpm.particles.seeding import _block_edges, seed_bodies
from parmpm.particles.seeding.polar import Rings

CENTRE = np.array([0.31, -0.27])


def _sector_quadrature(r1, r2, t1, t2, n=24):
    """Area and centroid of an annular sector by Gauss-Legendre in r and θ (the Jacobian r
    integrated exactly by the rule): independent of the closed forms of the seeding."""
    g, w = np.polynomial.legendre.leggauss(n)
    r = 0.5 * (r2 - r1) * g + 0.5 * (r1 + r2)
    t = 0.5 * (t2 - t1) * g + 0.5 * (t1 + t2)
    wr, wt = 0.5 * (r2 - r1) * w, 0.5 * (t2 - t1) * w
    R, T = np.meshgrid(r, t, indexing="ij")
    W = np.outer(wr, wt) * R
    area = W.sum()
    return area, np.array([(W * R * np.cos(T)).sum(), (W * R * np.sin(T)).sum()]) / area


@pytest.mark.parametrize("per_radius", [1, 5, 20, 80])
def test_every_cell_is_its_sector_area_and_centroid(per_radius):
    radius = 0.4
    rings = Rings(CENTRE, radius, radius / per_radius, _block_edges)
    ids = np.arange(len(rings))
    x = rings.points(ids)
    area, lh0, r0 = rings.domains(ids)
    # the cells tile the disk: ring j from j Δr to (j+1) Δr, m_j equal sectors from angle 0
    for i in np.unique(np.linspace(0, len(rings) - 1, 40).astype(int)):
        j = np.searchsorted(rings.ring_first, i, side="right") - 1
        k, m = i - rings.ring_first[j], rings.per_ring[j]
        a, c = _sector_quadrature(j * rings.dr, (j + 1) * rings.dr, 2 * np.pi * k / m,
                                  2 * np.pi * (k + 1) / m)
        assert area[i] == pytest.approx(a, rel=1e-12)
        np.testing.assert_allclose(x[i] - CENTRE, c, rtol=0, atol=1e-12 * radius)
    # the mass is exact and the centre of mass at the centre, at every resolution
    assert area.sum() == pytest.approx(np.pi * radius ** 2, rel=1e-13)
    np.testing.assert_allclose((x * area[:, None]).sum(0) / area.sum(), CENTRE, atol=1e-14)
    # domains: CPDI's parallelogram (radial, tangential) of the cell's area, GIMP's equal square
    np.testing.assert_allclose(4.0 * np.abs(np.linalg.det(r0)), area, rtol=1e-12)
    np.testing.assert_allclose(np.einsum("nk,nk->n", r0[:, :, 0], r0[:, :, 1]), 0.0,
                               atol=1e-15)
    radial = r0[:, :, 0] / np.linalg.norm(r0[:, :, 0], axis=1)[:, None]
    towards = (x - CENTRE) / np.linalg.norm(x - CENTRE, axis=1)[:, None]
    np.testing.assert_allclose(np.einsum("nk,nk->n", radial, towards), 1.0, rtol=1e-12)
    np.testing.assert_allclose(lh0, 0.5 * np.sqrt(area)[:, None] * np.ones(2), rtol=1e-15)


def _disk_seeds(seeding_kind: str, per_radius: int, ppc: int = 2):
    sc = load_scene("spinning_disk", [f"bodies.0.seeding={seeding_kind}", f"bodies.0.ppc={ppc}",
                                      f"grid.cell_size={0.4 / per_radius}",
                                      f"grid.cells=[{3 * per_radius}, {3 * per_radius}]",
                                      f"grid.origin=[{-1.5 * 0.4}, {-1.5 * 0.4}]"])
    params, names = material_table(sc.spec.materials)
    seeds = seed_bodies(sc.spec.grid, sc.spec.bodies, {n: i for i, n in enumerate(names)})
    return sc.spec.bodies[0], seeds, params


def test_the_outline_is_followed_and_the_mass_exact_where_the_lattice_has_flats():
    """Per resolution: the seeded mass against ρ π R², and the outermost particle's distance
    from the centre in each of ``π R / s`` equal sectors (``s`` the spacing: two outer particles
    or more per sector), its spread in spacings: 0 when the outer particles lie on one circle;
    the lattice's steps make it a sizeable part of a spacing."""
    rows = []
    for per_radius in (5, 10, 20):
        for kind in ("conforming", "lattice"):
            body, seeds, params = _disk_seeds(kind, per_radius)
            x, mass = seeds.x, seeds.mass(params)
            exact = params[0, 1] * np.pi * body.radius ** 2
            d = x - np.asarray(body.center)
            spacing = 0.4 / per_radius / 2
            sectors = int(np.pi * body.radius / spacing)
            angle = np.floor((np.arctan2(d[:, 1], d[:, 0]) + np.pi) / (2 * np.pi) * sectors)
            far = np.zeros(sectors)
            np.maximum.at(far, angle.astype(int) % sectors, np.hypot(d[:, 0], d[:, 1]))
            spread = (far.max() - far.min()) / spacing
            rows.append((per_radius, kind, mass.sum() / exact - 1.0, spread))
    for per_radius, kind, mass_error, spread in rows:
        if kind == "conforming":
            assert abs(mass_error) < 1e-13 and spread < 1e-9, (per_radius, mass_error, spread)
        else:  # what the default no longer does: the outline in steps, the mass approximate
            assert spread > 0.3 and abs(mass_error) > 1e-4, (per_radius, mass_error, spread)


@pytest.mark.parametrize("block", [32, 4096])
def test_any_block_and_any_subset_give_the_same_particles(block, monkeypatch):
    monkeypatch.setattr(seeding, "BLOCK", block)
    _, seeds, params = _disk_seeds("conforming", 20)
    src = seeds.chunks[0][0]
    assert isinstance(src, Rings) and src.firsts[-1] == len(src)
    whole = seeds.particles(params)
    assert np.array_equal(np.concatenate([src.block(j) for j in range(src.firsts.size - 1)]),
                          whole.x)
    ids = np.sort(np.random.default_rng(3).choice(len(src), len(src) // 3, replace=False))
    part = seeds.particles(params, ids)
    for name in ("x", "x0", "vol0", "mass", "lh0", "r0", "v"):
        assert np.array_equal(getattr(part, name), getattr(whole, name)[ids]), name


def test_the_default_disk_is_conforming_and_the_lattice_an_option():
    sc = load_scene("spinning_disk")
    assert sc.spec.bodies[0].seeding == "conforming"
    lattice = load_scene("spinning_disk", ["bodies.0.seeding=lattice"])
    assert lattice.spec.bodies[0].seeding == "lattice"
    box = load_scene("hanging_bar")
    assert box.spec.bodies[0].seeding == "lattice"


@pytest.mark.parametrize("scene, over, message", [
    ("spinning_disk", ["bodies.0.seeding=polar"], 'bodies.0.seeding: expected one of'),
    ("hanging_bar", ["bodies.0.seeding=conforming"],
     'bodies.0.seeding: "conforming" is not yet available for shape "box"'),
    ("spinning_disk", ["bodies.0.seeding=3"], "bodies.0.seeding"),
    ("spinning_disk", ["bodies.0={shape='difference', material='disk', seeding='conforming', "
                       "parts=[{shape='disk', center=[0, 0], radius=0.4}, "
                       "{shape='disk', center=[0.1, 0], radius=0.1}]}"],
     'bodies.0.seeding: "conforming" is not yet available for shape "difference" with these '
     "parts (only for disk, sphere, cylinder"),
    ("spinning_disk", ["bodies.0={shape='polygon', material='disk', seeding='conforming', "
                       "vertices=[[0, 0], [0.2, 0], [0, 0.2]]}"],
     'bodies.0.seeding: "conforming" is not yet available for shape "polygon" (only for'),
])
def test_a_seeding_a_shape_lacks_is_a_one_line_error(scene, over, message):
    with pytest.raises(SceneError) as err:
        load_scene(scene, over)
    assert message in str(err.value) and "\n" not in str(err.value)


def test_a_tiny_disk_is_one_ring_of_three():
    rings = Rings(CENTRE, 1e-3, 1.0, _block_edges)
    assert len(rings) == 3 and math.isclose(rings.domains(np.arange(3))[0].sum(),
                                            math.pi * 1e-6, rel_tol=1e-14)
