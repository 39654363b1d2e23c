"""The contact's gap on a node's own line (:func:`parmpm.grid.near.line_span`,
:func:`parmpm.grid.contact.contact_extents`): where the line through a node along its normal
crosses the particle domains, against brute-force sampling of the domains and against the
geometry of a circle resting on a flat, where a node a distance ``s`` from the point of contact
sees a gap of ``R − √(R² − s²)`` (about ``s²/2R``) and is not in contact (issue 40)."""
from __future__ import annotations


import numpy as np
import pytest

from parmpm.grid.contact import GAP_MODES, contact_extents
from parmpm.grid.near import line_span
from parmpm.particles.seeding import _block_edges
from parmpm.particles.seeding.polar import Rings


def _sampled_span(r, q, n, samples=200_001):
    """The stretch of ``node + t n`` inside ``x_p + r a`` (``|a_j| ≤ 1``), from points along
    the line each tested for membership (numpy's solve for ``a``): the first and last inside."""
    t = np.linspace(-10.0, 10.0, samples)
    pts = t[:, None] * n - q  # x − x_p for points on the line (relative to the node)
    a = np.linalg.solve(r, pts.T).T
    inside = np.all(np.abs(a) <= 1.0, axis=1)
    return (t[inside].min(), t[inside].max()) if inside.any() else (1.0, -1.0)


@pytest.mark.parametrize("d", [1, 2, 3])
def test_the_line_s_stretch_in_a_domain_is_the_sampled_one(d):
    rng = np.random.default_rng(d)
    inv = np.zeros((3, 3))
    hits = 0
    for _ in range(12):
        r = np.zeros((3, 3))
        r[:d, :d] = rng.normal(size=(d, d)) * 0.5 + np.eye(d)
        n = np.zeros(3)
        n[:d] = rng.normal(size=d)
        n /= np.linalg.norm(n)
        q = np.zeros(3)
        q[:d] = rng.normal(size=d) * 0.6
        lo, hi = line_span(d, r, q, n[:d].copy(), inv)
        slo, shi = _sampled_span(r[:d, :d], q[:d], n[:d])
        if slo > shi:  # the line misses the domain: so must the slab test (or only just hit)
            assert lo > hi or hi - lo < 2e-4
            continue
        hits += 1
        assert lo == pytest.approx(slo, abs=2e-4) and hi == pytest.approx(shi, abs=2e-4)
    assert hits >= 4
    # a flat domain is missed, a line parallel to a face pair inside or outside it
    flat = np.zeros((3, 3))
    flat[0, 0] = 1.0
    assert np.subtract(*line_span(2, flat, np.zeros(3), np.array([0.0, 1.0]), inv)) > 0
    square = np.diag([1.0, 1.0, 0.0])
    assert line_span(2, square, np.array([0.5, 3.0, 0.0]), np.array([0.0, 1.0]), inv) == (
        pytest.approx(2.0), pytest.approx(4.0))
    assert np.subtract(*line_span(2, square, np.array([1.5, 3.0, 0.0]),
                                  np.array([0.0, 1.0]), inv)) > 0


#: the contact point a third of a spacing off a node column. The outer ring's rectangles leave
#: V-shaped notches between them, half a spacing deep and about s²/2R wide at the surface (a
#: parallelogram cannot fill an annular sector); a line along a sector boundary (the bottom one
#: when the ring's sector count is a multiple of 4) would see half a spacing of gap there. Off the
#: node columns by a third of a spacing, no node line of this test falls into one.
XC = 0.37


def _disk_on_flat(per_radius: int, gap: str = "line"):
    """A disk (R = 0.1, rings) touching the flat top (y = 0) of a lattice block at
    ``x = XC``, one patch slot over the grid, normals vertical (out of the block: +y; out of the
    disk: −y); the block's gap at every node, and the node positions."""
    R, h = 0.1, 0.1 / per_radius
    s = h / 2
    rings = Rings([XC * s, R], R, s, _block_edges)
    ids = np.arange(len(rings))
    _, _, r0_disk = rings.domains(ids)
    xs = np.arange(-1.4 * R + s / 2, 1.4 * R, s)
    ys = np.arange(-4 * s + s / 2, 0.0, s)
    bx, by = np.meshgrid(xs, ys, indexing="ij")
    block = np.stack([bx.ravel(), by.ravel()], axis=1)
    x2 = np.concatenate([block, rings.points(ids)])
    n = x2.shape[0]
    x = np.zeros((n, 3))
    x[:, :2] = x2
    r0 = np.zeros((n, 3, 3))
    r0[:block.shape[0], 0, 0] = r0[:block.shape[0], 1, 1] = s / 2
    r0[block.shape[0]:, :2, :2] = r0_disk
    F = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    field = np.concatenate([np.zeros(block.shape[0], np.int64), np.ones(len(rings), np.int64)])
    origin = np.array([-2.0 * R, -0.05, 0.0])  # nodes at multiples of h about the contact
    nloc = np.array([round(4 * R / h) + 1, round(0.3 / h) + 1, 1])
    stride = int(np.prod(nloc))
    normal = np.zeros((2, 1, 4, stride))  # the first candidate only
    normal[0, 0, 1], normal[1, 0, 1] = 1.0, -1.0
    ext = np.full((2, 1, 4, stride), -np.inf)
    contact_extents(2, np.array([0, n]), np.arange(n, dtype=np.uint64), field, x, F, r0,
                    origin, np.array([h, h, 1.0]), 1.0, np.zeros((1, 3), np.int64), nloc,
                    normal, np.ones((1, 1, stride)), np.array([True]), ext, None,
                    GAP_MODES[gap])
    gap = -(ext[0, 0, 0] + ext[0, 0, 1])
    i0, i1 = np.meshgrid(np.arange(nloc[0]), np.arange(nloc[1]), indexing="ij")
    node_x = origin[0] + i0.T.ravel() * h
    node_y = origin[1] + i1.T.ravel() * h
    return R, s, gap, node_x, node_y


@pytest.mark.parametrize("per_radius", [5, 10, 20])
def test_a_node_beside_the_contact_point_sees_the_circle_s_gap(per_radius):
    """Every node near the two surfaces whose line crosses both: the gap is the circle's height
    above the flat at the node's abscissa, to a small part of a spacing (the outer ring is a
    polygon of parallelograms); beside the disk the line misses it: no contact."""
    R, s, gap, nx, ny = _disk_on_flat(per_radius)
    near = (ny > -2 * s) & (ny < R) & np.isfinite(gap)
    dx = nx - XC * s  # from the point of contact
    inside = near & (np.abs(dx) < 0.8 * R)
    exact = R - np.sqrt(R * R - dx[inside] ** 2)
    assert inside.sum() >= 6
    assert np.abs(gap[inside] - exact).max() < 0.05 * s
    # the node a cell off the contact point is apart by about (Δx)²/2R > 0: not in contact
    cell = 2 * s
    off = inside & (np.abs(dx) > 0.5 * cell) & (np.abs(dx) < 1.5 * cell)
    assert off.any() and (gap[off] > 0.2 * cell ** 2 / (2 * R)).all()
    # beside the disk no line crosses it: an infinite gap
    assert np.isinf(gap[(np.abs(dx) > 1.05 * R) & (ny > -2 * s) & (ny < R)]).all()


def test_the_column_gap_closes_a_cell_early_beside_the_contact_point():
    """The default ("column") counts every domain in the node's column, half a cell and a
    domain wide: a node a cell off the contact point sees the disk's lowest particle in its
    column, so the gap it reports is well under the circle's height there (R/Δx = 20)."""
    R, s, gap, nx, ny = _disk_on_flat(20, "column")
    dx = nx - XC * s
    cell = 2 * s
    off = ((ny > -2 * s) & (ny < R) & (np.abs(dx) > 0.5 * cell) & (np.abs(dx) < 1.5 * cell)
           & np.isfinite(gap))
    exact = R - np.sqrt(R * R - dx[off] ** 2)
    assert off.sum() >= 2 and (gap[off] < 0.5 * exact).all()
