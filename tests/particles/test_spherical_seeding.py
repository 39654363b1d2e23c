"""A sphere seeded "conforming" (:mod:`parmpm.particles.seeding.spherical`): shells of bands and
sectors whose outer particles follow the surface, each cell's exact volume as its own, against
independent quadrature and against the lattice seeding."""
from __future__ import annotations

import math

import numpy as np
import pytest

from parmpm import load_scene
from parmpm.core.errors import SceneError
from parmpm.materials import material_table
from parmpm.particles import seeding
from parmpm.particles.seeding import _block_edges, seed_bodies
from parmpm.particles.seeding.spherical import Shells

CENTRE = np.array([0.31, -0.27, 0.05])


def _cell_quadrature(r1, r2, t1, t2, p1, p2, n=12):
    """Volume and centroid of a spherical cell by Gauss-Legendre in r, θ and φ (Jacobian
    r² sin θ): independent of the seeding's closed forms."""
    g, w = np.polynomial.legendre.leggauss(n)
    axes = [(0.5 * (b - a) * g + 0.5 * (a + b), 0.5 * (b - a) * w)
            for a, b in ((r1, r2), (t1, t2), (p1, p2))]
    (r, wr), (t, wt), (p, wp) = axes
    R, T, P = np.meshgrid(r, t, p, indexing="ij")
    W = np.einsum("i,j,k->ijk", wr, wt, wp) * R ** 2 * np.sin(T)
    x = np.stack([R * np.sin(T) * np.cos(P), R * np.sin(T) * np.sin(P), R * np.cos(T)])
    vol = W.sum()
    return vol, (W * x).sum(axis=(1, 2, 3)) / vol


@pytest.mark.parametrize("per_radius", [1, 4, 12])
def test_every_cell_is_its_exact_volume_and_centroid(per_radius):
    radius = 0.4
    shells = Shells(CENTRE, radius, radius / per_radius, _block_edges)
    ids = np.arange(len(shells))
    x = shells.points(ids)
    vol, lh0, r0 = shells.domains(ids)
    # the cells tile the sphere: shell, band (equal polar angles), sector (equal azimuths)
    for i in np.unique(np.linspace(0, len(shells) - 1, 30).astype(int)):
        b = np.searchsorted(shells.band_first, i, side="right") - 1
        j, m, k = shells.band_shell[b], shells.band_sectors[b], i - shells.band_first[b]
        t1, t2 = shells.band_theta[b]
        v, c = _cell_quadrature(j * shells.dr, (j + 1) * shells.dr, t1, t2,
                                2 * np.pi * k / m, 2 * np.pi * (k + 1) / m)
        assert vol[i] == pytest.approx(v, rel=1e-12)
        np.testing.assert_allclose(x[i] - CENTRE, c, rtol=0, atol=1e-12 * radius)
    # the mass is exact and the centre of mass at the centre, at every resolution
    assert vol.sum() == pytest.approx(4.0 / 3.0 * np.pi * radius ** 3, rel=1e-13)
    np.testing.assert_allclose((x * vol[:, None]).sum(0) / vol.sum(), CENTRE, atol=1e-13)
    # CPDI's parallelepiped (radial, polar, azimuthal: right-handed, orthogonal) holds the
    # cell's volume, its first vector along the radius; GIMP's cube the same volume
    np.testing.assert_allclose(8.0 * np.linalg.det(r0), vol, rtol=1e-12)
    gram = np.einsum("nai,naj->nij", r0, r0)
    off = gram - np.einsum("nii->ni", gram)[:, :, None] * np.eye(3)
    assert np.abs(off).max() < 1e-12 * radius ** 2
    radial = r0[:, :, 0] / np.linalg.norm(r0[:, :, 0], axis=1)[:, None]
    towards = (x - CENTRE) / np.linalg.norm(x - CENTRE, axis=1)[:, None]
    np.testing.assert_allclose(np.einsum("nk,nk->n", radial, towards), 1.0, rtol=1e-12)
    np.testing.assert_allclose(lh0, 0.5 * np.cbrt(vol)[:, None] * np.ones(3), rtol=1e-14)


def _sphere_seeds(kind: str, per_radius: int):
    r = 0.1
    h = 2 * r / per_radius  # ppc 2: spacing r / per_radius
    sc = load_scene("hanging_bar_3d", [
        f"bodies.0={{shape='sphere', center=[0.0, 0.0, 0.0], radius={r}, material='bar', "
        f"seeding='{kind}'}}", f"grid.cell_size={h}", "grid.origin=[-0.2, -0.2, -0.2]",
        f"grid.cells=[{round(0.4 / h)}, {round(0.4 / h)}, {round(0.4 / h)}]",
        "boundary={}", "loads=[]"])
    params, names = material_table(sc.spec.materials)
    seeds = seed_bodies(sc.spec.grid, sc.spec.bodies, {n: i for i, n in enumerate(names)})
    return sc.spec.bodies[0], seeds, params


def test_the_surface_is_followed_and_the_mass_exact_where_the_lattice_has_steps():
    """Per resolution: the seeded mass against ρ (4/3) π R³ and the outermost particle's
    distance from the centre in each of 2 (R/s)² equal-area patches of the sphere (``s``
    the spacing), its spread in spacings: below a thousandth on shells (measured 1e-4; the centroid
    of a cell depends a little on its angular shape), 0.13-0.8 of a spacing on the lattice."""
    rows = []
    for per_radius in (8, 12, 16):
        for kind in ("conforming", "lattice"):
            body, seeds, params = _sphere_seeds(kind, per_radius)
            x, mass = seeds.x, seeds.mass(params)
            exact = params[0, 1] * 4.0 / 3.0 * np.pi * body.radius ** 3
            d = x - np.asarray(body.center)
            dist = np.linalg.norm(d, axis=1)
            spacing = body.radius / per_radius
            # equal-area patches: cos θ and φ in equal steps
            nz, nphi = per_radius, 2 * per_radius
            iz = np.minimum((0.5 * (d[:, 2] / dist + 1) * nz).astype(int), nz - 1)
            ip = np.minimum(((np.arctan2(d[:, 1], d[:, 0]) + np.pi) / (2 * np.pi) * nphi)
                            .astype(int), nphi - 1)
            far = np.zeros(nz * nphi)
            np.maximum.at(far, iz * nphi + ip, dist)
            assert far.min() > 0, (per_radius, kind)  # every patch has a particle
            rows.append((per_radius, kind, mass.sum() / exact - 1.0,
                         (far.max() - far.min()) / spacing))
    for per_radius, kind, mass_error, spread in rows:
        if kind == "conforming":
            assert abs(mass_error) < 1e-13 and spread < 0.01, (per_radius, mass_error, spread)
        else:
            assert spread > 0.1 and abs(mass_error) > 1e-4, (per_radius, mass_error, spread)


@pytest.mark.parametrize("block", [32, 4096])
def test_any_block_and_any_subset_give_the_same_particles(block, monkeypatch):
    monkeypatch.setattr(seeding, "BLOCK", block)
    _, seeds, params = _sphere_seeds("conforming", 8)
    src = seeds.chunks[0][0]
    assert isinstance(src, Shells) and src.firsts[-1] == len(src)
    whole = seeds.particles(params)
    assert np.array_equal(np.concatenate([src.block(j) for j in range(src.firsts.size - 1)]),
                          whole.x)
    ids = np.sort(np.random.default_rng(5).choice(len(src), len(src) // 3, replace=False))
    part = seeds.particles(params, ids)
    for name in ("x", "x0", "vol0", "mass", "lh0", "r0", "v"):
        assert np.array_equal(getattr(part, name), getattr(whole, name)[ids]), name


def test_the_default_sphere_is_conforming_and_a_tiny_one_an_error():
    body, seeds, _ = _sphere_seeds("conforming", 4)
    sc = load_scene("hanging_bar_3d", ["bodies.0={shape='sphere', center=[0.5, -0.5, 0.5], "
                                       "radius=0.45, material='bar'}"])
    assert sc.spec.bodies[0].seeding == "conforming"
    tiny = load_scene("hanging_bar_3d", ["bodies.0={shape='sphere', center=[0.5, -0.5, 0.5], "
                                         "radius=1e-4, material='bar'}"])
    params, names = material_table(tiny.spec.materials)
    with pytest.raises(SceneError, match="a sphere of radius 0.0001 m is smaller than half"):
        seed_bodies(tiny.spec.grid, tiny.spec.bodies, {n: i for i, n in enumerate(names)})


def test_a_one_shell_sphere_is_four_cells_of_the_whole_volume():
    shells = Shells(CENTRE, 1e-3, 1.0, _block_edges)
    assert len(shells) == 4 and math.isclose(shells.domains(np.arange(4))[0].sum(),
                                             4.0 / 3.0 * math.pi * 1e-9, rel_tol=1e-14)
