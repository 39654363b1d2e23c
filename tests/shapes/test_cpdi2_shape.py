"""Property tests of the CPDI2 weights (:mod:`parmpm.shapes.cpdi2`).

Random domains are perturbed parallelepipeds whose isoparametric map has ``det J > 0`` at every
reference corner (2D: exactly the convex quadrilaterals), on non-square cells, in 1D/2D/3D, with
the particle position off the domain's centroid. Seeded numpy RNG, so failures reproduce; each
check runs compiled and through ``.py_func`` (fewer samples). Checked:

1. partition of unity, ``Σ ∇φ = 0``, ``Σ x_i ⊗ ∇φ_ip = I`` and ``Σ φ_ip x_i`` = the domain's
   (volume-weighted) centroid;
2. ``wf``, ``wg`` equal the integrals by a 5-point-per-axis Gauss rule (the 2-point rule is exact);
3. an affine domain ``corners = F·R0·s_α`` gives CPDI1's entries, node by node (also capped, 1D/2D);
4. the cap: corners within ``l_cr`` bit for bit, longer ones shrunk to ``l_cr`` along themselves,
   an unreached cap changes no entry bit for bit, a capped support keeps property 1;
5. reach: -1 when a corner's nodes leave the patch's box or the grid;
6. an inverted, collapsed or NaN domain: -2; a non-convex quadrilateral with ``V > 0`` is accepted.
"""
import math

import numpy as np
import pytest

from decomposition import PatchLayout
from parmpm.shapes.cpdi import cpdi_support
from parmpm.shapes.cpdi2 import INVERTED, OUT_OF_BOX, SCRATCH_SHAPE, WF, WG, cap_corners, cpdi2_support
from parmpm.shapes.scaling import scale_domain

TOL = 1e-12
CELLS = 12
H = np.array([1.0, 0.7, 1.3])  # non-cubic cells
DIMS = [pytest.param(d, id=f"{d}d") for d in (1, 2, 3)]
PATHS = [pytest.param(True, id="jit"), pytest.param(False, id="py")]
SAMPLES = {True: 40, False: 5}


def _signs(d):
    """``s_αm`` in the kernel's bit order: bit ``m`` of ``α`` set ↔ ``+1``."""
    return np.array([[1.0 if (a >> m) & 1 else -1.0 for m in range(d)] for a in range(1 << d)])


def _fn(f, jit):
    return f if jit else f.py_func


def _call(d, x, corners, lcr=math.inf, h=None, layout=None, coords=(0, 0, 0), jit=True):
    """Run ``cpdi2_support`` for a particle at ``x`` in the patch ``coords`` of ``layout``
    (default: one patch over a ``CELLS``-cell grid). Returns (code, nodes, w, g, scratch): global
    node coordinates (n, d), weights, gradients (n, d) — empty unless code > 0."""
    h = H[:d] if h is None else h
    layout = PatchLayout((CELLS,) * d, (CELLS,) * d, 3) if layout is None else layout
    base = layout.local_base(np.array(coords, np.int64))
    nloc, nglob = layout.local_nodes3, layout.global_nodes3
    inv_h = np.concatenate([1.0 / h, np.ones(3 - d)])
    xi = np.zeros(3)
    xi[:d] = x / h
    jk, wk, dwk = np.zeros((3, 2), np.int64), np.zeros((3, 2)), np.zeros((3, 2))
    idx, w, g = np.zeros(64, np.int64), np.zeros(64), np.zeros((64, 3))
    scratch = np.zeros(SCRATCH_SHAPE)
    n = _fn(cpdi2_support, jit)(d, xi, np.ascontiguousarray(corners, float), float(lcr), base,
                                nloc, nglob, inv_h, int(nloc[0]), int(nloc[1]), jk, wk, dwk,
                                idx, w, g, scratch)
    return n, *_nodes(d, n, idx, base, nloc, h), w[:max(n, 0)], g[:max(n, 0), :d], scratch


def _nodes(d, n, idx, base, nloc, h):
    loc = idx[:max(n, 0)]
    ijk = np.stack([loc % nloc[0], (loc // nloc[0]) % nloc[1], loc // (nloc[0] * nloc[1])], axis=1)
    return ((ijk + base)[:, :d] * h,)


def _by_node(nodes, w, g, h):
    """{node index tuple: (Σ weight, Σ gradient)} (corners share nodes)."""
    acc = {}
    for xn, wi, gi in zip(nodes, w, g):
        key = tuple(int(k) for k in np.rint(xn / h))
        w0, g0 = acc.get(key, (0.0, 0.0))
        acc[key] = (w0 + wi, g0 + gi)
    return acc


def _assert_same_by_node(a, b, d, wtol, gtol, msg=""):
    for key in set(a) | set(b):
        w0, g0 = a.get(key, (0.0, np.zeros(d)))
        w1, g1 = b.get(key, (0.0, np.zeros(d)))
        assert abs(w0 - w1) <= wtol, (msg, key, w0, w1)
        np.testing.assert_allclose(g1, g0, rtol=0, atol=gtol, err_msg=f"{msg} node {key}")


def _random_F(rng, d, amp=0.3, min_det=0.3):
    while True:
        F = np.eye(d) + amp * rng.standard_normal((d, d))
        if np.linalg.det(F) > min_det:
            return F


def _reference(c, order=5):
    """(V, wf (2^d,), wg (2^d, d)) of the domain with corners ``c`` by an ``order``-point Gauss
    rule per axis, in numpy: an independent evaluation of the integrals."""
    nc, d = c.shape
    s = _signs(d)
    pts, wts = np.polynomial.legendre.leggauss(order)
    vol, wf, wg = 0.0, np.zeros(nc), np.zeros((nc, d))
    for k in np.ndindex(*(order,) * d):
        xi, wq = pts[list(k)], np.prod(wts[list(k)])
        f = 0.5 * (1.0 + s * xi)                      # (nc, d) per-axis factors
        N = f.prod(axis=1)
        dN = np.stack([0.5 * s[:, m] * np.prod(np.delete(f, m, axis=1), axis=1)
                       for m in range(d)], axis=1)    # dN[α, m] = ∂N_α/∂ξ_m
        J = c.T @ dN
        det = np.linalg.det(J)
        vol += wq * det
        wf += wq * det * N
        wg += wq * det * dN @ np.linalg.inv(J)
    return vol, wf / vol, wg / vol


def _jacobian_dets_at_corners(c):
    d = c.shape[1]
    s = _signs(d)
    dets = []
    for xi in s:
        f = 0.5 * (1.0 + s * xi)
        dN = np.stack([0.5 * s[:, m] * np.prod(np.delete(f, m, axis=1), axis=1)
                       for m in range(d)], axis=1)
        dets.append(np.linalg.det(c.T @ dN))
    return np.array(dets)


def _random_domain(rng, d):
    """A particle inside the grid and its corners relative to it: a random parallelepiped of
    half-widths up to 0.6 cells with each corner moved by up to ~0.3 of the smallest half-width,
    kept when ``det J > 0`` at every reference corner; ``x_p`` off the centroid."""
    h = H[:d]
    while True:
        lh = rng.uniform(0.15, 0.6, d) * h
        c = _signs(d) * lh @ _random_F(rng, d).T
        c += 0.3 * lh.min() * rng.uniform(-1.0, 1.0, c.shape)
        c -= 0.2 * lh.min() * rng.uniform(-1.0, 1.0, d)
        if np.all(_jacobian_dets_at_corners(c) > 0.05 * np.prod(lh)):
            return rng.uniform(4.0, 8.0, d) * h, c


def _samples(d, jit, seed):
    rng = np.random.default_rng([seed, d, int(jit)])
    for _ in range(SAMPLES[jit]):
        yield _random_domain(rng, d)


# --- 1: partition of unity, linear reproduction --------------------------------------------------

def _assert_properties(d, x, c, n, nodes, w, g, msg=""):
    assert n == 4 ** d, msg
    gscale = np.abs(g).max()
    assert abs(w.sum() - 1.0) <= TOL, msg
    np.testing.assert_allclose(g.sum(axis=0), 0.0, rtol=0, atol=TOL * gscale, err_msg=msg)
    np.testing.assert_allclose(nodes.T @ g, np.eye(d), rtol=0,
                               atol=TOL * np.abs(nodes).max() * gscale, err_msg=msg)
    vol, wf, _ = _reference(c)
    np.testing.assert_allclose(w @ nodes, x + wf @ c, rtol=0, atol=TOL * np.abs(nodes).max(),
                               err_msg=msg)


@pytest.mark.parametrize("jit", PATHS)
@pytest.mark.parametrize("d", DIMS)
def test_partition_of_unity_and_linear_reproduction(d, jit):
    for x, c in _samples(d, jit, seed=1):
        n, nodes, w, g, _ = _call(d, x, c, jit=jit)
        _assert_properties(d, x, c, n, nodes, w, g, msg=f"x={x} corners={c}")


# --- 2: the 2-point Gauss rule is exact ----------------------------------------------------------

@pytest.mark.parametrize("jit", PATHS)
@pytest.mark.parametrize("d", DIMS)
def test_weights_equal_high_order_quadrature(d, jit):
    for x, c in _samples(d, jit, seed=2):
        n, nodes, w, g, sc = _call(d, x, c, jit=jit)
        vol, wf, wg = _reference(c)
        nc = 1 << d
        np.testing.assert_allclose(sc[:nc, WF], wf, rtol=0, atol=TOL)
        gscale = np.abs(wg).max()
        np.testing.assert_allclose(sc[:nc, WG:WG + d], wg, rtol=0, atol=TOL * gscale)
        np.testing.assert_array_equal(sc[:nc, WG + d:WG + 3], 0.0)


# --- 3: an affine domain is CPDI1's --------------------------------------------------------------

def _cpdi1_by_node(d, x, R, h):
    layout = PatchLayout((CELLS,) * d, (CELLS,) * d, 3)
    base = layout.local_base(np.zeros(3, np.int64))
    nloc, nglob = layout.local_nodes3, layout.global_nodes3
    inv_h = np.concatenate([1.0 / h, np.ones(3 - d)])
    xi = np.zeros(3)
    xi[:d] = x / h
    R3, C = np.zeros((3, 3)), np.zeros((3, 3))
    R3[:d, :d] = R
    jk, wk, dwk = np.zeros((3, 2), np.int64), np.zeros((3, 2)), np.zeros((3, 2))
    idx, w, g = np.zeros(64, np.int64), np.zeros(64), np.zeros((64, 3))
    n = cpdi_support(d, xi, R3, C, base, nloc, nglob, inv_h, int(nloc[0]), int(nloc[1]),
                     jk, wk, dwk, idx, w, g)
    assert n == 4 ** d
    return _by_node(*_nodes(d, n, idx, base, nloc, h), w[:n], g[:n, :d], h)


@pytest.mark.parametrize("jit", PATHS)
@pytest.mark.parametrize("d, capped", [pytest.param(d, c, id=f"{d}d-{'capped' if c else 'unscaled'}")
                                      for d, c in ((1, False), (2, False), (3, False), (1, True),
                                                   (2, True))])
def test_affine_domain_equals_cpdi1(d, jit, capped):
    """``corners = F·R0·s_α`` (det F > 0): the entries agree with ``cpdi_support`` node by node.
    Capped (l_cr below the longest corner): in 1D and 2D CPDI1's cap yields exactly the capped
    corners (``±l_a', ±l_b'``); in 3D CPDI1 rebuilds a parallelepiped instead, so that pair is not
    compared (not generated, rather than skipped)."""
    rng = np.random.default_rng([3, d, int(jit), int(capped)])
    h = H[:d]
    for _ in range(SAMPLES[jit]):
        x = rng.uniform(4.0, 8.0, d) * h
        R = _random_F(rng, d) @ np.diag(rng.uniform(0.1, 0.9, d) * h)
        c = _signs(d) @ R.T
        lcr = math.inf
        if capped:
            lens = np.linalg.norm(c, axis=1)
            lcr = rng.uniform(0.5, 0.95) * lens.max()
            R3 = np.zeros((3, 3))
            R3[:d, :d] = R
            scale_domain(d, R3, lcr)
            R = R3[:d, :d]
        n, nodes, w, g, _ = _call(d, x, c, lcr=lcr, jit=jit)
        assert n == 4 ** d
        _assert_same_by_node(_cpdi1_by_node(d, x, R, h), _by_node(nodes, w, g, h), d,
                             wtol=1e-13, gtol=1e-13 / h.min(), msg=f"x={x} R={R} lcr={lcr}")


# --- 4: domain scaling ---------------------------------------------------------------------------

@pytest.mark.parametrize("jit", PATHS)
@pytest.mark.parametrize("d", DIMS)
def test_cap_corners(d, jit):
    rng = np.random.default_rng([4, d, int(jit)])
    cap = _fn(cap_corners, jit)
    for _ in range(SAMPLES[jit]):
        c = rng.standard_normal((1 << d, d)) * rng.uniform(0.1, 3.0)
        lens = np.linalg.norm(c, axis=1)
        for lcr in (math.inf, 1.5 * lens.max(), float(np.median(lens)), 0.5 * lens.min()):
            out = np.full((1 << d, d), np.nan)
            changed = cap(d, c, float(lcr), out)
            longer = lens > lcr
            assert changed == bool(longer.any())
            np.testing.assert_array_equal(out[~longer], c[~longer])  # bit for bit
            if longer.any():
                np.testing.assert_allclose(np.linalg.norm(out[longer], axis=1), lcr, rtol=1e-15)
                unit = c[longer] / lens[longer, None]
                np.testing.assert_allclose(out[longer], lcr * unit, rtol=0, atol=1e-15 * lcr)


@pytest.mark.parametrize("jit", PATHS)
@pytest.mark.parametrize("d", DIMS)
def test_unreached_cap_changes_nothing(d, jit):
    for x, c in _samples(d, jit, seed=5):
        _, nodes, w, g, sc = _call(d, x, c, jit=jit)
        reach = np.linalg.norm(c, axis=1).max()
        for lcr in (reach * (1.0 + 1e-14), 2.0 * reach):
            _, nodes2, w2, g2, sc2 = _call(d, x, c, lcr=lcr, jit=jit)
            for a, b in ((nodes, nodes2), (w, w2), (g, g2), (sc, sc2)):
                np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("jit", PATHS)
@pytest.mark.parametrize("d", DIMS)
def test_capped_support_within_lcr(d, jit):
    """Corners stretched up to 4× and capped at ``l_cr = 1.2·min Δx``: the support lies within
    ``l_cr`` of the particle (plus the corner's cell), and property 1 holds for the capped
    domain."""
    h = H[:d]
    lcr = 1.2 * h.min()
    rng = np.random.default_rng([6, d, int(jit)])
    checked = 0
    for x, c in _samples(d, jit, seed=6):
        c = c * rng.uniform(1.5, 4.0)
        n, nodes, w, g, sc = _call(d, x, c, lcr=lcr, jit=jit)
        capped = sc[:1 << d, :d].copy()
        assert np.linalg.norm(capped, axis=1).max() <= lcr * (1 + 1e-15)
        assert np.all(np.abs(nodes - x) <= lcr + h), (x, c)
        if np.any(_jacobian_dets_at_corners(capped) <= 0):
            continue  # capping may fold the map near a corner: the reference's inv(J) fails there
        checked += 1
        _assert_properties(d, x, capped, n, nodes, w, g, msg=f"x={x} corners={c}")
    assert checked >= SAMPLES[jit] // 2


# --- 5: reach ------------------------------------------------------------------------------------

@pytest.mark.parametrize("d", DIMS)
def test_reach_beyond_patch_box_and_grid(d):
    """Patches of 4 cells with 1 ghost: the patch owning cells 4..7 holds global nodes 3..9 per
    axis. From ``x = 7.7`` cells, corners reaching node 8.0 fit, 10.1 do not, unless capped at
    ``l_cr = 0.9·min Δx``; near the grid's far face likewise."""
    h = H[:d]
    layout = PatchLayout((CELLS,) * d, (4,) * d, 1)
    mid = (1,) * d + (0,) * (3 - d)
    c = 0.3 * _signs(d) * h
    x = np.full(d, 7.7) * h  # in cell 7 of the patch owning cells 4..7
    assert _call(d, x, c, layout=layout, coords=mid)[0] == 4 ** d
    assert _call(d, x, c * 8.0, layout=layout, coords=mid)[0] == OUT_OF_BOX
    assert _call(d, x, c * 8.0, lcr=0.9 * h.min(), layout=layout, coords=mid)[0] == 4 ** d
    edge = np.full(d, CELLS - 0.2) * h
    assert _call(d, edge, c * 0.5)[0] == 4 ** d
    assert _call(d, edge, c)[0] == OUT_OF_BOX


# --- 6: inverted domains -------------------------------------------------------------------------

@pytest.mark.parametrize("jit", PATHS)
@pytest.mark.parametrize("d", DIMS)
def test_inverted_domain(d, jit):
    h = H[:d]
    x = np.full(d, 6.3) * h
    c = 0.3 * _signs(d) * h
    mirrored = c.copy()
    mirrored[:, 0] *= -1.0  # the same corners in clockwise (left-handed) order: V < 0
    collapsed = c.copy()
    collapsed[:, -1] = 0.0  # zero volume
    nan = c.copy()
    nan[1, 0] = np.nan
    for bad in (mirrored, collapsed, nan):
        assert _call(d, x, bad, jit=jit)[0] == INVERTED
        assert _call(d, x, 40.0 * bad, jit=jit)[0] == INVERTED  # reported before the reach
    assert _call(d, x, c, jit=jit)[0] == 4 ** d


@pytest.mark.parametrize("jit", PATHS)
def test_nonconvex_quad_is_accepted(jit):
    """A dart (reflex corner 3, ``det J < 0`` there, ``V > 0``): entries, not -2, and they keep
    partition of unity and linear reproduction (the centroid by the polygon formula), though a
    corner weight is negative."""
    h = H[:2]
    x = np.array([6.3, 6.1]) * h
    c = np.array([[-0.4, -0.4], [0.4, -0.3], [-0.3, 0.4], [-0.3, -0.3]]) * h  # tour 0, 1, 3, 2
    assert np.any(_jacobian_dets_at_corners(c) < 0)
    n, nodes, w, g, sc = _call(2, x, c, jit=jit)
    assert n == 16
    assert np.any(sc[:4, WF] < 0)
    p = c[[0, 1, 3, 2]]
    q = np.roll(p, -1, axis=0)
    cross = p[:, 0] * q[:, 1] - q[:, 0] * p[:, 1]
    area = 0.5 * cross.sum()
    centroid = ((p + q) * cross[:, None]).sum(axis=0) / (6.0 * area)
    assert abs(w.sum() - 1.0) <= TOL
    np.testing.assert_allclose(nodes.T @ g, np.eye(2), rtol=0, atol=TOL * np.abs(nodes).max() / h.min())
    np.testing.assert_allclose(w @ nodes, x + centroid, rtol=0, atol=TOL * np.abs(nodes).max())
