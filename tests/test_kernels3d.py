"""The hand-specialised 3D kernels (:mod:`parmpm.kernels3d`) against the dimension-generic ones
(:mod:`parmpm.transfer`), on the 3D hanging bar with several patches and a randomly deformed,
moving, stressed particle state: P2G sums, the MUSL momentum re-map and every G2P mode
(positions, velocities, F, stress, the CFL speed) agree to round-off, with and without domain
scaling (an ``l_cr`` that caps most but not all domains), body forces and both materials; a
support past the ghost layer is caught the same way. The CPDI kernels also run through
``.py_func`` (readable failures, coverage)."""
import numpy as np
import pytest

import parmpm
from parmpm.grid import grid_block
from parmpm.kernels2d.cells import cell_of
from parmpm.kernels3d import KERNELS_3D
from parmpm.kernels3d.cells import cells_of8
from parmpm.kernels3d.material import stress_pass
from parmpm.materials import MODELS
from parmpm.shapes import CPDI
from parmpm.simulation import Simulation
from parmpm.transfer import G2P_MUSL_DEFORM, G2P_MUSL_MOTION, G2P_USL
from parmpm.transfer import stress_pass as generic_stress_pass

QUIET = ["output.snapshots=false", "output.figure=false", "time.steps=1"]
#: l_cr (m) below most deformed corner lengths of the 3D bar (Δx = 0.2 m, 3 ppc: 0.058 m at F = I)
LCR = 0.07


def deformed_stepper(method, lcr, model="neo_hookean", seed=1, tmp=None):
    """A stepper on the 3D hanging bar (patches of 4 cells) whose particles have random
    velocities, deformation gradients ``F = Q U`` (rotation × stretch/shear near 1), and
    symmetric stresses."""
    over = QUIET + [f'method.interpolator="{method}"', "grid.patch_size=4",
                    f'materials.bar.model="{model}"']
    if method == "cpdi":
        over.append(f"method.lcr={lcr}")
    sim = Simulation(parmpm.load_scene("hanging_bar_3d", over), tmp, quiet=True)
    st, P = sim.stepper, sim.stepper.P
    rng = np.random.default_rng(seed)
    n = P.n
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1)[:, None]
    th = rng.uniform(-0.4, 0.4, n)
    K = np.zeros((n, 3, 3))
    K[:, 0, 1], K[:, 0, 2], K[:, 1, 2] = -axis[:, 2], axis[:, 1], -axis[:, 0]
    K -= K.transpose(0, 2, 1)
    Q = np.eye(3) + np.sin(th)[:, None, None] * K + (1 - np.cos(th))[:, None, None] * (K @ K)
    U = np.zeros((n, 3, 3))
    U[:, [0, 1, 2], [0, 1, 2]] = rng.uniform(0.8, 1.4, (n, 3))
    U[:, [0, 0, 1], [1, 2, 2]] = rng.uniform(-0.15, 0.15, (n, 3))
    P.F[:] = Q @ U
    P.v[:] = rng.normal(0.0, 1.0, (n, 3))
    S = rng.normal(0.0, 1e4, (n, 3, 3))
    P.stress[:] = S + S.transpose(0, 2, 1)
    return sim, st, P


def snapshot(P):
    return {k: getattr(P, k).copy() for k in ("x", "v", "F", "stress", "dx")}


def restore(P, snap):
    for k, a in snap.items():
        getattr(P, k)[:] = a


def close(a, b, rtol=1e-12):
    scale = max(1.0, float(np.max(np.abs(b))))
    np.testing.assert_allclose(a, b, rtol=0, atol=rtol * scale)


CASES = [("cpdi", "none"), ("cpdi", LCR), ("mpm", "none")]


def test_lcr_engages_on_some_domains(tmp_path):
    sim, st, P = deformed_stepper("cpdi", LCR, tmp=tmp_path)
    scaled = parmpm.domain_vectors(3, CPDI, LCR, P.F, P.r0, P.lh0)
    free = parmpm.domain_vectors(3, CPDI, 0.0, P.F, P.r0, P.lh0)
    changed = np.any(scaled != free, axis=(1, 2))
    assert 0.2 < changed.mean() < 0.95


@pytest.mark.parametrize("method,lcr", CASES)
@pytest.mark.parametrize("forced", [False, True])
def test_p2g_matches_generic(method, lcr, forced, tmp_path):
    sim, st, P = deformed_stepper(method, lcr, tmp=tmp_path)
    assert st.kernels is KERNELS_3D[st.disc.method]
    bforce = np.random.default_rng(2).normal(0, 5.0, (P.n, 3)) if forced else np.zeros((0, 3))
    st._p2g(bforce)
    fast = st.gsum.copy()
    st.kernels = None
    st._p2g(bforce)
    assert np.max(st.gsum[:, :, 0]) > 0 and st.error is None
    close(fast, st.gsum)
    st.kernels = KERNELS_3D[st.disc.method]
    st._p2g_momentum()
    fast_mv = st.gmv.copy()
    st.gsum[:] = 0.0
    st.kernels = None
    st._p2g_momentum()
    close(fast_mv, st.gmv)


@pytest.mark.parametrize("method,lcr", CASES)
@pytest.mark.parametrize("mode", [G2P_USL, G2P_MUSL_MOTION, G2P_MUSL_DEFORM])
@pytest.mark.parametrize("model", sorted(MODELS))
def test_g2p_matches_generic(method, lcr, mode, model, tmp_path):
    sim, st, P = deformed_stepper(method, lcr, model, tmp=tmp_path)
    rng = np.random.default_rng(3)
    st.gnew[:] = rng.normal(0.0, 1.0, st.gnew.shape)
    P.dx[:] = rng.normal(0.0, 1e-4, P.dx.shape)
    before = snapshot(P)
    dt, results = 1e-4, []
    for kern in (KERNELS_3D[st.disc.method], None):
        restore(P, before)
        st.kernels = kern
        vmax = st._g2p(mode, dt)
        assert st.error is None
        results.append((snapshot(P), vmax))
    (fast, vf), (gen, vg) = results
    for k in fast:
        close(fast[k], gen[k])
    if mode != G2P_MUSL_MOTION:
        assert vf == pytest.approx(vg, rel=1e-13) and vf > 0
        assert not np.array_equal(fast["F"], before["F"])


@pytest.mark.parametrize("model", sorted(MODELS))
def test_stress_pass_matches_generic(model, tmp_path):
    sim, st, P = deformed_stepper("mpm", "none", model, tmp=tmp_path)
    fast, gen = np.empty_like(P.stress), np.empty_like(P.stress)
    cf = stress_pass(P.F, P.mat, st.params, fast)
    cg = generic_stress_pass(3, P.F, P.mat, st.params, P.damage, gen)
    close(fast, gen)
    assert cf == pytest.approx(cg, rel=1e-13)


def test_reach_past_ghost_layer_is_caught_like_generic(tmp_path):
    sim, st, P = deformed_stepper("cpdi", "none", tmp=tmp_path)
    P.F[7] = np.diag([30.0, 1.0, 1.0])  # a domain 5 cells long: past the 2-cell ghost layer
    for kern in (KERNELS_3D[st.disc.method], None):
        st.kernels = kern
        st.err[0] = -1
        st._p2g(np.zeros((0, 3)))
        assert st.err[0] == -1 and st.error is not None and "reaches" in st.error
        assert f"particle {P.gid[7]} " in st.error
        st.error = None
        st._g2p(G2P_USL, 1e-4)
        st._check("g2p")
        assert st.error is not None and f"particle {P.gid[7]} " in st.error
        st.error = None


@pytest.mark.parametrize("jit", [True, False])
def test_cells_of8_is_cell_of_per_corner(jit):
    """The fast path (every floor usable) and the snapping / out-of-box path give
    :func:`cell_of` of each corner (box: base 2, usable cells 2..9)."""
    f = cells_of8 if jit else cells_of8.py_func
    inside = [2.5, 3.0, 9.75, 5.25, 4.0, 6.5, 7.125, 8.0]
    for c in (inside, inside[:7] + [10.0], inside[:7] + [10.0 + 1e-12],
              [2.0 - 1e-12] + inside[1:], inside[:3] + [1.5] + inside[4:], inside[:7] + [10.5]):
        got = f(*c, 2, 2, 9)
        want = [cell_of(ci, 2, 2, 9) for ci in c]
        assert got[:8] == tuple(w[0] for w in want) and got[8:16] == tuple(w[1] for w in want)
        assert got[16] == all(w[0] >= 0 for w in want)


def test_kernels_through_py_func(tmp_path):
    """The CPDI kernels' Python bodies give the compiled results (one occupied patch)."""
    sim, st, P = deformed_stepper("cpdi", LCR, tmp=tmp_path)
    D = st.disc
    s = int(np.flatnonzero(np.diff(P.start) > 0)[0])
    one = slice(s, s + 1)
    args = (D.lcr, P.start[s:s + 2], D.base[one], D.jlo[one], D.jhi[one], D.nloc,
            D.origin3, D.inv_h3)
    fields = (P.x, P.v, P.F, P.r0, P.mass, P.vol0, P.stress, np.zeros((0, 3)))
    p2g, _, g2p = KERNELS_3D[D.method]
    nodes = D.layout.n_local_nodes
    blocks = [grid_block(1, 7, nodes)[0] for _ in range(2)]
    err = np.full(1, -1, np.int64)
    p2g(*args, *fields, blocks[0], err)
    p2g.py_func(*args, *fields, blocks[1], err)
    assert err[0] == -1 and blocks[0][0, 0].sum() > 0
    close(blocks[1], blocks[0], 1e-15)
    gnew = np.random.default_rng(4).normal(0.0, 1.0, grid_block(1, 6, nodes)[0].shape)
    before, out = snapshot(P), []
    lay = D.layout
    loc = np.array([lay.cells3, lay.psize3, lay.patches_per_axis], np.int64)
    for f in (g2p, g2p.py_func):
        restore(P, before)
        new = np.full(P.n, -7, np.int64)
        located = f(G2P_USL, *args, 1e-4, 0.9, P.x, P.v, P.F, P.r0, P.stress, P.dx, P.mat,
                    st.params, P.damage, gnew, err, loc, 1.0 / lay.psize3, st.patches.local_ids[one], new)
        out.append((snapshot(P), located, new))
    assert err[0] == -1
    for k in before:
        close(out[1][0][k], out[0][0][k], 1e-15)
    assert out[1][1] == out[0][1] and out[0][1][0] > 0
    np.testing.assert_array_equal(out[1][2], out[0][2])
