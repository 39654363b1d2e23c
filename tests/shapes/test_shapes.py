"""Property tests of every interpolator.

Each property is checked on random particles (seeded numpy RNG, so failures reproduce) for all four
interpolators in 1D, 2D and 3D on non-cubic cells, through the compiled kernels and through their
pure-Python bodies (``jit=False`` runs ``.py_func`` of ``domain_matrix`` and ``particle_support``):

1. partition of unity ``Σ_i φ_ip = 1``;
2. ``Σ_i ∇φ_ip = 0``;
3. linear-field gradient reproduction ``Σ_i x_i ⊗ ∇φ_ip = I``;
4. linear-field reproduction ``Σ_i φ_ip x_i = x_p`` (for GIMP/CPDI: the average of a linear field
   over a domain symmetric about ``x_p`` is its value at ``x_p``);
5. mirror symmetry about the grid centre;
6. cpdi = ugimp = mpm for an undeformed domain inside one cell;
7. CPDI domain scaling (``l_cr > 0``): the corner bound, bit-for-bit identity when nothing is
   capped, the material ``F`` untouched, the exact 2D rebuild, and the 3D uniform rescale.

Tolerances are ``TOL = 1e-12`` relative to the scale of the compared quantity.
"""
import itertools

import numpy as np
import pytest
from shape_harness import domain, entries

from parmpm.shapes import BSPLINE, CPDI, CPGIMP, MPM, UGIMP

TOL = 1e-12
CELLS = 12
H = np.array([1.0, 0.7, 1.3])  # non-cubic cells
METHODS = [pytest.param(MPM, id="mpm"), pytest.param(UGIMP, id="ugimp"),
           pytest.param(CPGIMP, id="cpgimp"), pytest.param(CPDI, id="cpdi"),
           pytest.param(BSPLINE, id="bspline")]
DIMS = [pytest.param(d, id=f"{d}d") for d in (1, 2, 3)]
# STYLE item 4: every assertion runs compiled and through .py_func (fewer samples, same checks)
PATHS = [pytest.param(True, id="jit"), pytest.param(False, id="py")]
SAMPLES = {True: 40, False: 6}


def _h(d):
    return H[:d].copy()


def _random_F(rng, d, amp=0.2, min_det=0.3):
    """Moderate deformation gradient ``I + amp·randn`` with ``det F > min_det``."""
    while True:
        F = np.eye(d) + amp * rng.standard_normal((d, d))
        if np.linalg.det(F) > min_det:
            return F


def _random_particle(rng, d):
    """Centre well inside the grid (cells 4..8 of 12 per axis), moderate F, GIMP/CPDI half-widths
    ``Δx/(2·ppc)`` for a random ppc ∈ {1, 2, 3}."""
    h = _h(d)
    x = rng.uniform(4.0, 8.0, d) * h
    ppc = rng.integers(1, 4)
    return x, _random_F(rng, d), h / (2.0 * ppc), h


def _samples(method, d, jit, seed):
    rng = np.random.default_rng([seed, method, d, int(jit)])
    for _ in range(SAMPLES[jit]):
        x, F, lh0, h = _random_particle(rng, d)
        out = entries(method, d, x, F=F, lh0=lh0, h=h, jit=jit)
        assert out is not None, f"support of a particle at {x} left the grid"
        yield x, F, lh0, h, out


def _by_node(nodes, w, g, h):
    """Sum entries per node (cpdi yields one entry per corner, so nodes repeat): {index tuple:
    (weight, gradient)}."""
    acc = {}
    for xi, wi, gi in zip(nodes, w, g):
        key = tuple(int(k) for k in np.rint(xi / h))
        w0, g0 = acc.get(key, (0.0, np.zeros(len(h))))
        acc[key] = (w0 + wi, g0 + gi)
    return acc


# --- 1–4: partition of unity, zero gradient sum, linear reproduction ----------------------------

@pytest.mark.parametrize("jit", PATHS)
@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("method", METHODS)
def test_partition_of_unity(method, d, jit):
    for x, F, lh0, h, (nodes, w, g, R) in _samples(method, d, jit, seed=1):
        assert abs(w.sum() - 1.0) <= TOL, (x, F)
        assert np.all(w >= -TOL)


@pytest.mark.parametrize("jit", PATHS)
@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("method", METHODS)
def test_gradients_sum_to_zero(method, d, jit):
    for x, F, lh0, h, (nodes, w, g, R) in _samples(method, d, jit, seed=2):
        scale = np.abs(g).max()  # ~1/Δx
        np.testing.assert_allclose(g.sum(axis=0), 0.0, atol=TOL * scale, err_msg=f"{x} {F}")


@pytest.mark.parametrize("jit", PATHS)
@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("method", METHODS)
def test_linear_gradient_reproduction(method, d, jit):
    for x, F, lh0, h, (nodes, w, g, R) in _samples(method, d, jit, seed=3):
        scale = np.abs(nodes).max() * np.abs(g).max()  # size of the summed terms
        np.testing.assert_allclose(nodes.T @ g, np.eye(d), rtol=0, atol=TOL * scale,
                                   err_msg=f"{x} {F}")


@pytest.mark.parametrize("jit", PATHS)
@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("method", METHODS)
def test_linear_reproduction(method, d, jit):
    for x, F, lh0, h, (nodes, w, g, R) in _samples(method, d, jit, seed=4):
        np.testing.assert_allclose(w @ nodes, x, rtol=0, atol=TOL * np.abs(nodes).max(),
                                   err_msg=f"{F}")


# --- 5: mirror symmetry -------------------------------------------------------------------------

@pytest.mark.parametrize("jit", PATHS)
@pytest.mark.parametrize("d", DIMS)
@pytest.mark.parametrize("method", METHODS)
def test_mirror_symmetry(method, d, jit):
    """Mirroring ``x_p`` about the grid centre on axis ``a`` (and ``F → M F M``, ``M`` = diag(±1))
    mirrors the weights node for node and flips the ``a`` component of the gradients."""
    for x, F, lh0, h, (nodes, w, g, R) in _samples(method, d, jit, seed=5):
        base = _by_node(nodes, w, g, h)
        gscale = np.abs(g).max()
        for a in range(d):
            M = np.eye(d)
            M[a, a] = -1.0
            xm = x.copy()
            xm[a] = CELLS * h[a] - x[a]
            out = entries(method, d, xm, F=M @ F @ M, lh0=lh0, h=h, jit=jit)
            assert out is not None
            mirrored = _by_node(*out[:3], h)
            for key in set(base) | {k[:a] + (CELLS - k[a],) + k[a + 1:] for k in mirrored}:
                km = key[:a] + (CELLS - key[a],) + key[a + 1:]
                w0, g0 = base.get(key, (0.0, np.zeros(d)))
                w1, g1 = mirrored.get(km, (0.0, np.zeros(d)))
                assert abs(w0 - w1) <= TOL, (a, key, w0, w1)
                np.testing.assert_allclose(M @ g1, g0, rtol=0, atol=TOL * gscale,
                                           err_msg=f"axis {a} node {key}")


# --- 6: cpdi = ugimp = mpm for an undeformed domain inside one cell -----------------------------

@pytest.mark.parametrize("jit", PATHS)
@pytest.mark.parametrize("d", DIMS)
def test_cpdi_ugimp_mpm_agree_inside_one_cell(d, jit):
    """With ``F = I`` and a domain of half-widths ``l ≤`` the distance to the cell faces, the
    GIMP average of the hat, the mean of the hats at the CPDI corners and the hat at the centre
    coincide (``S_i`` is linear inside a cell), and so do their gradients."""
    rng = np.random.default_rng([6, d, int(jit)])
    h = _h(d)
    for s in range(SAMPLES[jit]):
        cell = rng.integers(3, 9, d)
        lh0 = rng.uniform(0.02, 0.49, d) * h
        x = (cell + rng.uniform(0.0, 1.0, d)) * h
        x = np.clip(x, cell * h + lh0, (cell + 1) * h - lh0)
        if s % 4 == 0:  # the domain touching a face of its cell
            x[0] = cell[0] * h[0] + lh0[0]
        results = {}
        for name, method in (("mpm", MPM), ("ugimp", UGIMP), ("cpdi", CPDI)):
            out = entries(method, d, x, lh0=lh0, h=h, jit=jit)
            assert out is not None
            results[name] = _by_node(*out[:3], h)
        gscale = 1.0 / h.min()
        ref = results["mpm"]
        for name in ("ugimp", "cpdi"):
            for key in set(ref) | set(results[name]):
                w0, g0 = ref.get(key, (0.0, np.zeros(d)))
                w1, g1 = results[name].get(key, (0.0, np.zeros(d)))
                assert abs(w0 - w1) <= TOL, (name, x, lh0, key, w0, w1)
                np.testing.assert_allclose(g1, g0, rtol=0, atol=TOL * gscale,
                                           err_msg=f"{name} x={x} l={lh0} node {key}")


# --- 7: CPDI domain scaling ---------------------------------------------------------------------

def _corners(R):
    """All 2^d centre-to-corner vectors ``Σ_k s_k r_k`` (rows)."""
    d = R.shape[0]
    S = np.array(list(itertools.product((-1.0, 1.0), repeat=d)))
    return S @ R.T


def _seed_rebuild(R, lcr):
    """Numpy re-implementation of the seed's algorithm: cap the centre-to-corner
    vectors at ``lcr`` and rebuild ``R'`` from them — without the final uniform rescale.
    Returns (R', whether any vector was capped)."""
    d = R.shape[0]

    def cap(v):
        n = np.linalg.norm(v)
        return (v * (lcr / n), True) if n > lcr else (v, False)

    if d == 1:
        return (np.array([[np.sign(R[0, 0]) * lcr]]), True) if abs(R[0, 0]) > lcr else (R, False)
    r = [R[:, k] for k in range(d)]
    if d == 2:
        (la, ca), (lb, cb) = cap(r[0] + r[1]), cap(r[0] - r[1])
        return np.stack([(la + lb) / 2, (la - lb) / 2], axis=1), ca or cb
    (la, ca), (lb, cb) = cap(r[0] + r[1] + r[2]), cap(r[0] - r[1] + r[2])
    (lc, cc), (ld, cd) = cap(-r[0] + r[1] + r[2]), cap(-r[0] - r[1] + r[2])
    Rp = np.stack([(la + lb - lc - ld) / 4, (la - lb + lc - ld) / 4, (la + lb + lc + ld) / 4], axis=1)
    return Rp, ca or cb or cc or cd


def _stretched_F(rng, d, max_stretch=6.0):
    """A strong deformation: stretch ``λ ∈ [1, max_stretch]`` along a random direction, a random
    shear and a random rotation (det F = λ > 0)."""
    n = rng.standard_normal(d)
    n /= np.linalg.norm(n)
    lam = rng.uniform(1.0, max_stretch)
    stretch = np.eye(d) + (lam - 1.0) * np.outer(n, n)
    shear = np.eye(d) + np.triu(0.8 * rng.standard_normal((d, d)), 1)
    Q, _ = np.linalg.qr(rng.standard_normal((d, d)))
    if np.linalg.det(Q) < 0:
        Q[:, 0] *= -1.0
    return Q @ stretch @ shear


def _loop_product(F, r0):
    """``F·R0`` summed in the kernel's order (k ascending from 0.0), for bit-for-bit comparison."""
    d = F.shape[0]
    R = np.zeros((d, d))
    for a in range(d):
        for b in range(d):
            acc = 0.0
            for k in range(d):
                acc += F[a, k] * r0[k, b]
            R[a, b] = acc
    return R


@pytest.mark.parametrize("jit", PATHS)
@pytest.mark.parametrize("d", DIMS)
def test_domain_scaling(d, jit):
    rng = np.random.default_rng([7, d, int(jit)])
    h = _h(d)
    lcr = 2.0 * h.min()
    n = 600 if jit else 60
    counts = dict(untouched=0, capped=0, fits=0, rescaled=0, both_2d=0)
    for s in range(n):
        if s % 7 == 0:  # isotropic growth: all corners capped alike, the rebuild fits (also 3D)
            Q, _ = np.linalg.qr(rng.standard_normal((d, d)))
            F = rng.uniform(2.0, 4.0) * Q * np.sign(np.linalg.det(Q))
        elif s % 5 == 0:
            F = _random_F(rng, d)
        else:
            F = _stretched_F(rng, d)
        F_before = F.copy()
        lh0 = h / (2.0 * rng.integers(1, 4))
        r0 = np.diag(lh0)
        x = 0.5 * CELLS * h  # grid centre: even unscaled domains stay inside the grid
        scaled = entries(CPDI, d, x, F=F, lh0=lh0, lcr=lcr, h=h, cells=CELLS, jit=jit)
        assert scaled is not None
        Rp, R = scaled[3], domain(d, F, r0, lcr=None, jit=jit)
        # the material F is never touched (only R' is scaled)
        np.testing.assert_array_equal(F, F_before)
        # R = F·R0 (no scaling), bit for bit in the kernel's summation order
        np.testing.assert_array_equal(R, _loop_product(F, r0))
        # the bound: no centre-to-corner vector of R' longer than lcr, in every dimension
        assert np.linalg.norm(_corners(Rp), axis=1).max() <= lcr * (1 + TOL), (F, Rp)
        rebuilt, capped = _seed_rebuild(R, lcr)
        if not capped:  # nothing exceeds lcr: R' is R, bit for bit
            assert np.linalg.norm(_corners(R), axis=1).max() <= lcr
            np.testing.assert_array_equal(Rp, R)
            counts["untouched"] += 1
            continue
        counts["capped"] += 1
        longest = np.linalg.norm(_corners(rebuilt), axis=1).max()
        if longest > lcr * (1 + TOL):
            # the seed's rebuild alone overshoots (3D only): R' is it, scaled uniformly to lcr
            counts["rescaled"] += 1
            expected = rebuilt * (lcr / longest)
            assert np.isclose(np.linalg.norm(_corners(Rp), axis=1).max(), lcr, rtol=TOL, atol=0)
        else:
            counts["fits"] += 1
            expected = rebuilt
        np.testing.assert_allclose(Rp, expected, rtol=0, atol=TOL * lcr)
        if d == 1:
            assert Rp[0, 0] == np.sign(R[0, 0]) * lcr  # the clamp is exact
        if d == 2:
            # exact rebuild: the corners of R' are l_a, l_b, each shrunk to lcr if it exceeded
            for sgn in (1.0, -1.0):
                l = R[:, 0] + sgn * R[:, 1]
                want = l * min(1.0, lcr / np.linalg.norm(l))
                np.testing.assert_allclose(Rp[:, 0] + sgn * Rp[:, 1], want, rtol=0, atol=1e-14 * lcr)
            if min(np.linalg.norm(R[:, 0] + R[:, 1]), np.linalg.norm(R[:, 0] - R[:, 1])) > lcr:
                counts["both_2d"] += 1
                assert np.allclose(np.linalg.norm(_corners(Rp), axis=1), lcr, rtol=1e-14, atol=0)
        # interpolation with the scaled domain keeps the properties 1–4
        nodes, w, g, _ = scaled
        assert abs(w.sum() - 1.0) <= TOL
        np.testing.assert_allclose(g.sum(axis=0), 0.0, atol=TOL * np.abs(g).max())
        np.testing.assert_allclose(nodes.T @ g, np.eye(d), rtol=0,
                                   atol=TOL * np.abs(nodes).max() * np.abs(g).max())
        np.testing.assert_allclose(w @ nodes, x, rtol=0, atol=TOL * np.abs(nodes).max())
    # the samples exercise every branch
    assert counts["untouched"] > 0 and counts["fits"] > 0, counts
    if d == 3:
        assert counts["rescaled"] > 0, counts  # the case where the seed's rebuild alone overshoots
    else:
        assert counts["rescaled"] == 0, counts  # 1D/2D rebuilds are exact
    if d == 2:
        assert counts["both_2d"] > 0, counts


# --- cpGIMP domains collapsed along an axis (regression) ---------------------------------------
# The weight used to be (Φ(ξ+l−j) − Φ(ξ−l−j))/2l in absolute grid coordinates, which cancels for a
# half-width l = l0·|F_kk| ≪ 1 (0 at a 90° rotation, NaN at F_kk = 0). gimp_axis now averages the
# hat piecewise between its kinks, so a collapsed domain gives the hat at its centre.

@pytest.mark.parametrize("fkk", [0.0, np.cos(np.pi / 2), 1e-9, 1e-3])
def test_cpgimp_partition_of_unity_for_collapsed_domain(fkk):
    """cpGIMP is meant to misbehave under large rotation, but as a shape function:
    a domain of vanishing width is the hat at the centre, whose weights still sum to one."""
    F = np.array([[fkk, -1.0], [1.0, fkk]])
    x = np.array([5.3, 4.2]) * _h(2)
    nodes, w, g, _ = entries(CPGIMP, 2, x, F=F, h=_h(2))
    assert np.all(np.isfinite(w)) and np.all(np.isfinite(g))
    assert abs(w.sum() - 1.0) <= TOL
    np.testing.assert_allclose(w @ nodes, x, rtol=0, atol=TOL * np.abs(nodes).max())
