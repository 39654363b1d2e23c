"""Conforming seeding beyond the disk and the sphere: an annulus in rings (a CSG disk minus
concentric disks, :mod:`parmpm.particles.seeding.polar`), a cylinder or tube in rings extruded in
layers (:mod:`parmpm.particles.seeding.cylindrical`), and which CSG bodies are round
(:func:`parmpm.geometry.circular.round_form`). Each cell against independent Gauss-Legendre
quadrature, the mass against the exact area or volume at several resolutions, the same bits on
any block and any subset, and the lattice kept (and conforming refused) where the geometry is
not round."""
from __future__ import annotations

import math

import numpy as np
import pytest

from parmpm.core.errors import SceneError
from parmpm.geometry.circular import round_form
from parmpm.particles import seeding
from parmpm.particles.seeding import _block_edges, _Masked, seed_bodies
from parmpm.particles.seeding.cylindrical import Tube, frame
from parmpm.particles.seeding.polar import Rings
from parmpm.particles.seeding.spherical import Shells
from parmpm.scene.load import scene_from_toml

RHO = 1000.0
PARAMS = np.array([[0.0, RHO] + [0.0] * 8])
SCENE = """
dim = {dim}
[grid]
cell_size = {h}
cells = {cells}
origin = {origin}
[materials.steel]
model = "linear_elastic"
density = {rho}
youngs_modulus = 1e6
poisson_ratio = 0.3
[[bodies]]
material = "steel"
ppc = 2
{body}
[time]
steps = 1
"""
C2 = [0.513, 0.487]
C3 = [0.513, 0.487, 0.502]


def annulus(r_out=0.4, r_in=0.25, centre=C2, inner_centre=None):
    inner_centre = centre if inner_centre is None else inner_centre
    return (f'shape = "difference"\nparts = [{{shape = "disk", center = {centre}, '
            f'radius = {r_out}}}, {{shape = "disk", center = {inner_centre}, radius = {r_in}}}]')


def cylinder(axis="z", r=0.3, length=0.6, centre=C3):
    return (f'{{shape = "cylinder", axis = "{axis}", center = {centre}, radius = {r}, '
            f'length = {length}}}')


def tube(axis="z", r_out=0.3, r_in=0.18, length=0.6, inner_length=None):
    inner = cylinder(axis, r_in, length if inner_length is None else inner_length)
    return f'shape = "difference"\nparts = [{cylinder(axis, r_out, length)}, {inner}]'


def scene(body: str, dim: int = 2, h: float = 0.1):
    n = round(1.0 / h)
    return scene_from_toml(SCENE.format(dim=dim, h=h, cells=[n] * dim, origin=[0.0] * dim,
                                        rho=RHO, body=body), "conforming.toml")


def seeds_of(sc):
    return seed_bodies(sc.spec.grid, sc.spec.bodies, {"steel": 0})


# --- every cell against quadrature ----------------------------------------------------------------
def _gauss(a, b, n):
    """Gauss-Legendre nodes and weights on [a, b] per row of ``a``, ``b`` (shape (cells, n))."""
    g, w = np.polynomial.legendre.leggauss(n)
    a, b = np.asarray(a, float)[:, None], np.asarray(b, float)[:, None]
    return 0.5 * (b - a) * g + 0.5 * (a + b), 0.5 * (b - a) * w


def _ring_bounds(rings: Rings, ids):
    """Each cell's radii and angles, read from the ring table (not from the seeding's formulas)."""
    j = np.searchsorted(rings.ring_first, ids, side="right") - 1
    k, m = ids - rings.ring_first[j], rings.per_ring[j]
    r1 = rings.inner + (rings.radius - rings.inner) * j / len(rings.per_ring)
    r2 = rings.inner + (rings.radius - rings.inner) * (j + 1) / len(rings.per_ring)
    return r1, r2, 2 * np.pi * k / m, 2 * np.pi * (k + 1) / m


def _sector_quadrature(r1, r2, t1, t2, n=16):
    """Area and centroid of annular sectors, Gauss-Legendre in r and θ (Jacobian r)."""
    (r, wr), (t, wt) = _gauss(r1, r2, n), _gauss(t1, t2, n)
    W = wr[:, :, None] * wt[:, None, :] * r[:, :, None]
    R, T = r[:, :, None], t[:, None, :]
    area = W.sum(axis=(1, 2))
    centroid = np.stack([(W * R * np.cos(T)).sum(axis=(1, 2)),
                         (W * R * np.sin(T)).sum(axis=(1, 2))], axis=1) / area[:, None]
    return area, centroid


@pytest.mark.parametrize("per_wall", [1, 4, 16])
def test_every_annulus_cell_is_its_sector_area_and_centroid(per_wall):
    r_out, r_in = 0.4, 0.25
    rings = Rings(C2, r_out, (r_out - r_in) / per_wall, _block_edges, inner=r_in)
    assert len(rings.per_ring) == per_wall and rings.per_ring.min() >= 3
    ids = np.arange(len(rings))
    x = rings.points(ids)
    area, lh0, r0 = rings.domains(ids)
    a, c = _sector_quadrature(*_ring_bounds(rings, ids))
    np.testing.assert_allclose(area, a, rtol=1e-12)
    np.testing.assert_allclose(x - C2, c, rtol=0, atol=1e-12 * r_out)
    assert area.sum() == pytest.approx(np.pi * (r_out ** 2 - r_in ** 2), rel=1e-13)
    np.testing.assert_allclose((x * area[:, None]).sum(0) / area.sum(), C2, atol=1e-14)
    # CPDI's parallelogram (radial, tangential) holds the cell's area, GIMP's square too
    np.testing.assert_allclose(4.0 * np.linalg.det(r0), area, rtol=1e-12)
    np.testing.assert_allclose(lh0, 0.5 * np.sqrt(area)[:, None] * np.ones(2), rtol=1e-15)
    # cells about square: a ring's sector about as long as the ring is wide
    arc = 2 * np.linalg.norm(r0[:, :, 1], axis=1) / (2 * np.linalg.norm(r0[:, :, 0], axis=1))
    assert 0.8 < arc.min() and arc.max() < 1.25, (arc.min(), arc.max())


def _tube_quadrature(tube: Tube, ids, n=8):
    """Volume and centroid (in the tube's frame: e₁, e₂, axis from the mid-point) of its cells,
    Gauss-Legendre in r, θ and z (Jacobian r)."""
    per = tube.per_layer
    layer, cell = ids // per, ids % per
    r1, r2, t1, t2 = _ring_bounds(tube.section, cell)
    z1 = -0.5 * tube.length + tube.length * layer / tube.layers
    z2 = -0.5 * tube.length + tube.length * (layer + 1) / tube.layers
    (r, wr), (t, wt), (z, wz) = _gauss(r1, r2, n), _gauss(t1, t2, n), _gauss(z1, z2, n)
    R, T, Z = r[:, :, None, None], t[:, None, :, None], z[:, None, None, :]
    W = wr[:, :, None, None] * wt[:, None, :, None] * wz[:, None, None, :] * R
    vol = W.sum(axis=(1, 2, 3))
    local = np.stack([(W * R * np.cos(T)).sum(axis=(1, 2, 3)),
                      (W * R * np.sin(T)).sum(axis=(1, 2, 3)),
                      (W * Z).sum(axis=(1, 2, 3))], axis=1)
    return vol, local / vol[:, None]


@pytest.mark.parametrize("axis, inner, per_radius", [
    ((0.0, 0.0, 1.0), 0.0, 1), ((0.0, 1.0, 0.0), 0.0, 5), ((1.0, 0.0, 0.0), 0.12, 4),
    ((1.0, 2.0, -3.0), 0.2, 6), ((0.0, 0.0, -1.0), 0.05, 3)])
def test_every_cylinder_cell_is_its_volume_and_centroid(axis, inner, per_radius):
    r_out, length = 0.3, 0.55
    t = Tube(C3, axis, r_out, length, r_out / per_radius, _block_edges, inner=inner)
    e1, e2, a = t.e1, t.e2, t.axis
    np.testing.assert_allclose(np.stack([e1, e2, a]) @ np.stack([e1, e2, a]).T, np.eye(3),
                               atol=1e-15)
    np.testing.assert_allclose(np.cross(e1, e2), a, atol=1e-15)  # right-handed
    np.testing.assert_allclose(a, np.asarray(axis) / np.linalg.norm(axis), atol=1e-15)
    ids = np.arange(len(t))
    x = t.points(ids)
    vol, lh0, r0 = t.domains(ids)
    v, local = _tube_quadrature(t, ids)
    np.testing.assert_allclose(vol, v, rtol=1e-12)
    np.testing.assert_allclose((x - C3) @ np.stack([e1, e2, a]).T, local, rtol=0,
                               atol=1e-12 * r_out)
    assert vol.sum() == pytest.approx(np.pi * (r_out ** 2 - inner ** 2) * length, rel=1e-13)
    np.testing.assert_allclose((x * vol[:, None]).sum(0) / vol.sum(), C3, atol=1e-14)
    # CPDI's box: radial, tangential, axial (right-handed, orthogonal), 8 det r0 = V
    np.testing.assert_allclose(8.0 * np.linalg.det(r0), vol, rtol=1e-12)
    gram = np.einsum("nai,naj->nij", r0, r0)
    off = gram - np.einsum("nii->ni", gram)[:, :, None] * np.eye(3)
    assert np.abs(off).max() < 1e-14 * r_out ** 2
    across = (x - C3) - np.outer((x - C3) @ a, a)
    radial = r0[:, :, 0] / np.linalg.norm(r0[:, :, 0], axis=1)[:, None]
    np.testing.assert_allclose(np.einsum("nk,nk->n", radial, across)
                               / np.linalg.norm(across, axis=1), 1.0, rtol=1e-12)
    np.testing.assert_allclose(r0[:, :, 2], np.tile(0.5 * t.dz * a, (len(t), 1)), rtol=1e-15)
    np.testing.assert_allclose(lh0, 0.5 * np.cbrt(vol)[:, None] * np.ones(3), rtol=1e-14)


def test_a_coordinate_axis_frame_is_the_next_two_axes():
    for k, (first, second) in enumerate([(1, 2), (2, 0), (0, 1)]):
        e1, e2, a = frame(np.eye(3)[k])
        assert np.array_equal(e1, np.eye(3)[first]) and np.array_equal(e2, np.eye(3)[second])


# --- the scene: mass, outline, bits ---------------------------------------------------------------
def _distances(x, centre, axis=None):
    """Each particle's distance from the centre (2D) or from the axis through it (3D)."""
    d = x - centre
    if axis is not None:
        d = d - np.outer(d @ axis, axis)
    dist = np.linalg.norm(d, axis=1)
    return dist


@pytest.mark.parametrize("kind", ["annulus", "cylinder", "tube"])
def test_the_mass_is_exact_and_the_outline_followed_at_every_resolution(kind):
    """Seeded mass against ρ × the exact area or volume at h = 0.1, 0.05, 0.025 (R/s = 6 to
    32; measured relative errors 0 to 2.2e-16: round-off, the cells being exact), and every
    particle of the outer (and inner) ring at one distance from the centre or axis (measured
    spreads up to 7.4e-16 of R: a few ulps of the centre's coordinates)."""
    rows = []
    for h in (0.1, 0.05, 0.025):
        if kind == "annulus":
            sc, exact, axis = scene(annulus(), 2, h), np.pi * (0.4 ** 2 - 0.25 ** 2), None
            centre, r_out, r_in = np.array(C2), 0.4, 0.25
        else:
            body = ('shape = "union"\nparts = [' + cylinder("y") + "]" if kind == "cylinder"
                    else tube("y"))
            r_in = 0.0 if kind == "cylinder" else 0.18
            sc, exact, axis = scene(body, 3, h), np.pi * (0.3 ** 2 - r_in ** 2) * 0.6, np.eye(3)[1]
            centre, r_out = np.array(C3), 0.3
        assert sc.spec.bodies[0].seeding == "conforming"
        seeds = seeds_of(sc)
        src = seeds.chunks[0][0]
        assert isinstance(src, Rings if kind == "annulus" else Tube)
        error = seeds.mass(PARAMS).sum() / (RHO * exact) - 1.0
        dist = _distances(seeds.x, centre, axis)
        ring = src.dr if kind == "annulus" else src.section.dr
        outer = dist[dist > dist.max() - 0.5 * ring]
        inner = dist[dist < dist.min() + 0.5 * ring]
        rows.append((h, float(error), float(np.ptp(outer) / r_out), float(np.ptp(inner) / r_out)))
        assert outer.max() < r_out and (r_in == 0 or inner.min() > r_in)
    print(f"{kind}: (h, mass error, outer spread / R, inner spread / R):", rows)
    for h, error, outer, inner in rows:
        assert abs(error) < 2e-15 and outer < 4e-15 and (kind == "cylinder" or inner < 4e-15), \
            (h, error, outer, inner)


@pytest.mark.parametrize("block", [32, 4096])
@pytest.mark.parametrize("body, dim", [(annulus(), 2), (tube("x"), 3)])
def test_any_block_and_any_subset_give_the_same_particles(block, body, dim, monkeypatch):
    monkeypatch.setattr(seeding, "BLOCK", block)
    seeds = seeds_of(scene(body, dim, 0.05))
    src = seeds.chunks[0][0]
    assert isinstance(src, Rings | Tube) and src.firsts[-1] == len(src)
    whole = seeds.particles(PARAMS)
    assert np.array_equal(np.concatenate([src.block(j) for j in range(src.firsts.size - 1)]),
                          whole.x)
    ids = np.sort(np.random.default_rng(7).choice(len(src), len(src) // 3, replace=False))
    part = seeds.particles(PARAMS, ids)
    for name in ("x", "x0", "vol0", "mass", "lh0", "r0", "v"):
        assert np.array_equal(getattr(part, name), getattr(whole, name)[ids]), name


@pytest.mark.parametrize("csg, plain, dim", [
    ('shape = "union"\nparts = [{shape = "disk", center = [0.5, 0.5], radius = 0.3}]',
     'shape = "disk"\ncenter = [0.5, 0.5]\nradius = 0.3', 2),
    ('shape = "difference"\nparts = [{shape = "union", parts = [{shape = "disk", '
     'center = [0.5, 0.5], radius = 0.3}]}]',
     'shape = "disk"\ncenter = [0.5, 0.5]\nradius = 0.3', 2),
    ('shape = "union"\nparts = [{shape = "sphere", center = [0.5, 0.5, 0.5], radius = 0.3}]',
     'shape = "sphere"\ncenter = [0.5, 0.5, 0.5]\nradius = 0.3', 3),
    ('shape = "union"\nparts = [' + cylinder("x") + "]", 'shape = "cylinder"\naxis = "x"\n'
     f'center = {C3}\nradius = 0.3\nlength = 0.6', 3),
])
def test_a_round_csg_body_seeds_the_particles_of_its_primitive(csg, plain, dim):
    """A disk, sphere or cylinder inside a one-part combination gives the primitive's particles,
    bit for bit (the disk's: the rings of ``shape = "disk"``, inner radius 0)."""
    a, b = seeds_of(scene(csg, dim)), seeds_of(scene(plain, dim))
    assert type(a.chunks[0][0]) is type(b.chunks[0][0])
    assert isinstance(a.chunks[0][0], Rings | Shells | Tube)
    pa, pb = a.particles(PARAMS), b.particles(PARAMS)
    for name in ("x", "vol0", "mass", "lh0", "r0", "v"):
        assert np.array_equal(getattr(pa, name), getattr(pb, name)), name


# --- what is round, and what is not ---------------------------------------------------------------
@pytest.mark.parametrize("body, dim, name, inner", [
    (annulus(), 2, "annulus", 0.25),
    ('shape = "difference"\nparts = [{shape = "disk", center = [0.5, 0.5], radius = 0.4}, '
     '{shape = "disk", center = [0.5, 0.5], radius = 0.1}, '
     '{shape = "union", parts = [{shape = "disk", center = [0.5, 0.5], radius = 0.2}]}]', 2,
     "annulus", 0.2),
    (annulus(inner_centre=[0.513 * (1 + 1e-13), 0.487]), 2, "annulus", 0.25),
    (tube(), 3, "tube", 0.18),
    (tube(inner_length=0.8), 3, "tube", 0.18),
    ('shape = "intersection"\nparts = [' + cylinder() + "]", 3, "cylinder", 0.0),
])
def test_round_bodies_are_recognised(body, dim, name, inner):
    sc = scene(body, dim)
    form = round_form(sc.spec.bodies[0], dim)
    assert form.name == name and form.inner == inner
    assert sc.spec.bodies[0].seeding == "conforming"


@pytest.mark.parametrize("body, dim", [
    (annulus(inner_centre=[0.52, 0.487]), 2),                       # not concentric
    (annulus(inner_centre=[0.513 * (1 + 1e-9), 0.487]), 2),          # nor to 1e-12
    ('shape = "difference"\nparts = [{shape = "disk", center = [0.5, 0.5], radius = 0.4}, '
     '{shape = "disk", center = [0.5, 0.5], radius = 0.1}, '
     '{shape = "disk", center = [0.6, 0.5], radius = 0.1}]', 2),    # one removed disk off-centre
    ('shape = "union"\nparts = [{shape = "disk", center = [0.4, 0.5], radius = 0.3}, '
     '{shape = "disk", center = [0.6, 0.5], radius = 0.3}]', 2),
    ('shape = "difference"\nparts = [{shape = "disk", center = [0.5, 0.5], radius = 0.4}, '
     '{shape = "box", min = [0.4, 0.4], max = [0.6, 0.6]}]', 2),
    ('shape = "difference"\nparts = [{shape = "difference", parts = ['
     '{shape = "disk", center = [0.5, 0.5], radius = 0.4}, '
     '{shape = "disk", center = [0.5, 0.5], radius = 0.2}]}, '
     '{shape = "disk", center = [0.5, 0.5], radius = 0.1}]', 2),     # nested difference
    (tube(inner_length=0.5), 3),                                     # a blind hole
    ('shape = "difference"\nparts = [' + cylinder("z") + ", " + cylinder("x", 0.1) + "]", 3),
    ('shape = "difference"\nparts = [{shape = "sphere", center = [0.5, 0.5, 0.5], radius = 0.4},'
     ' {shape = "sphere", center = [0.5, 0.5, 0.5], radius = 0.2}]', 3),
])
def test_other_csg_bodies_keep_the_lattice(body, dim):
    sc = scene(body, dim)
    assert round_form(sc.spec.bodies[0], dim) is None
    assert sc.spec.bodies[0].seeding == "lattice"
    assert isinstance(seeds_of(sc).chunks[0][0], _Masked)
    with pytest.raises(SceneError) as err:
        scene(body + '\nseeding = "conforming"', dim)
    message = str(err.value)
    assert "\n" not in message and 'bodies.0.seeding: "conforming" is not yet available for ' \
        f'shape "{sc.spec.bodies[0].shape}" with these parts (only for disk, sphere, cylinder' \
        in message, message


def test_a_removed_disk_as_large_as_the_outer_one_is_empty_on_the_lattice():
    sc = scene(annulus(0.3, 0.3), 2)
    assert sc.spec.bodies[0].seeding == "lattice"
    with pytest.raises(SceneError, match="the difference holds no point of its particle lattice"):
        seeds_of(sc)


# --- small and bad sizes: clear errors ------------------------------------------------------------
@pytest.mark.parametrize("body, dim, message", [
    (annulus(0.4, 0.39), 2, "bodies.0: the wall of an annulus (0.4 m minus 0.39 m) is smaller than "
                            "half its particle spacing (0.05 m); thicken the wall or raise ppc"),
    (annulus(0.02, 0.01), 2, "bodies.0: an annulus of radius 0.02 m is smaller than half"),
    ('shape = "union"\nparts = [' + cylinder(r=0.01) + "]", 3,
     "bodies.0: a cylinder of radius 0.01 m is smaller than half its particle spacing"),
    (tube(length=0.02), 3, "bodies.0: a tube of length 0.02 m is smaller than half its particle "
                           "spacing (0.05 m); lengthen it or raise ppc"),
])
def test_a_body_thinner_than_half_a_spacing_is_an_error(body, dim, message):
    sc = scene(body, dim)
    with pytest.raises(SceneError) as err:
        seeds_of(sc)
    assert message in str(err.value) and "\n" not in str(err.value), str(err.value)


@pytest.mark.parametrize("body, dim, message", [
    (annulus(0.4, 0.0), 2, "bodies.0.parts.1.radius: expected a number > 0, got 0"),
    (annulus(0.4, float("nan")), 2, "bodies.0.parts.1.radius: expected a number > 0, got nan"),
    ('shape = "cylinder"\naxis = "z"\ncenter = [0.5, 0.5, 0.5]\nradius = nan\nlength = 0.5', 3,
     "bodies.0.radius: expected a number > 0, got nan"),
    ('shape = "cylinder"\naxis = "z"\ncenter = [0.5, 0.5, 0.5]\nradius = 0.2\nlength = 0.0', 3,
     "bodies.0.length: expected a number > 0, got 0"),
])
def test_zero_and_nan_sizes_are_scene_errors(body, dim, message):
    with pytest.raises(SceneError) as err:
        scene(body, dim)
    assert message in str(err.value) and "\n" not in str(err.value), str(err.value)


@pytest.mark.parametrize("make, message", [
    (lambda: Rings(C2, float("nan"), 0.1, _block_edges), "expected a finite radius > 0, got nan"),
    (lambda: Rings(C2, 0.0, 0.1, _block_edges), "expected a finite radius > 0, got 0.0"),
    (lambda: Rings(C2, 0.4, 0.1, _block_edges, inner=0.4), "expected an inner radius from 0"),
    (lambda: Rings(C2, 0.4, 0.1, _block_edges, inner=-0.1), "expected an inner radius from 0"),
    (lambda: Tube(C3, (0, 0, 1), 0.3, math.inf, 0.1, _block_edges), "expected a finite length"),
    (lambda: Tube(C3, (0, 0, 1), 0.3, 0.5, 0.1, _block_edges, inner=math.nan),
     "expected an inner radius from 0"),
])
def test_the_seedings_refuse_bad_radii(make, message):
    with pytest.raises(ValueError, match=message):
        make()
