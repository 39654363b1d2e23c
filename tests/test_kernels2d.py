"""The hand-specialised 2D kernels (:mod:`parmpm.kernels2d`) against the dimension-generic ones
(:mod:`parmpm.transfer`), on a small hanging-bar grid with several patches and a randomly
deformed, moving, stressed particle state: P2G sums, the MUSL momentum re-map and every G2P
mode (positions, velocities, F, stress, the CFL speed) agree to round-off, with and without
domain scaling, body forces and both materials; a support past the ghost layer is caught the
same way. The kernels also run through ``.py_func`` (readable failures, coverage)."""
import numpy as np
import pytest

import parmpm
from parmpm.grid import grid_block
from parmpm.kernels2d import KERNELS_2D
from parmpm.kernels2d.cells import cell_of, usable_cells
from parmpm.materials import MODELS
from parmpm.simulation import Simulation
from parmpm.transfer import G2P_MUSL_DEFORM, G2P_MUSL_MOTION, G2P_USL

QUIET = ["output.snapshots=false", "output.figure=false", "time.steps=1"]


def deformed_stepper(method, lcr, model="neo_hookean", seed=1, tmp=None):
    """A stepper on the 2D hanging bar (patches of 4 cells) whose particles have random
    velocities, deformation gradients near a rotation-stretch, and stresses."""
    over = QUIET + [f'method.interpolator="{method}"', "grid.patch_size=4",
                    f'materials.bar.model="{model}"', f"method.lcr={lcr}"]
    if method != "cpdi":
        over = over[:-1]
    scene = parmpm.load_scene("hanging_bar", over)
    sim = Simulation(scene, tmp, quiet=True)
    st, P = sim.stepper, sim.stepper.P
    rng = np.random.default_rng(seed)
    n = P.n
    th = rng.uniform(-0.4, 0.4, n)
    stretch = rng.uniform(0.8, 1.6, (n, 2))
    shear = rng.uniform(-0.2, 0.2, n)
    c, s = np.cos(th), np.sin(th)
    Rot = np.stack([np.stack([c, -s], 1), np.stack([s, c], 1)], 1)
    U = np.zeros((n, 2, 2))
    U[:, 0, 0], U[:, 1, 1], U[:, 0, 1] = stretch[:, 0], stretch[:, 1], shear
    P.F[:] = Rot @ U
    P.v[:] = rng.normal(0.0, 1.0, (n, 2))
    S = rng.normal(0.0, 1e4, (n, 2, 2))
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


CASES = [("cpdi", "none"), ("cpdi", 0.025), ("mpm", "none")]


@pytest.mark.parametrize("method,lcr", CASES)
@pytest.mark.parametrize("forced", [False, True])
def test_p2g_matches_generic(method, lcr, forced, tmp_path):
    sim, st, P = deformed_stepper(method, lcr, tmp=tmp_path)
    assert st.kernels is KERNELS_2D[st.disc.method]
    bforce = np.random.default_rng(2).normal(0, 5.0, (P.n, 2)) if forced else np.zeros((0, 2))
    st._p2g(bforce)
    fast = st.gsum.copy()
    st.kernels = None
    st._p2g(bforce)
    assert np.max(st.gsum[:, :, 0]) > 0 and st.error is None
    close(fast, st.gsum)
    st.kernels = KERNELS_2D[st.disc.method]
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
    for kern in (KERNELS_2D[st.disc.method], None):
        restore(P, before)
        st.kernels = kern
        vmax = st._g2p(mode, dt)
        results.append((snapshot(P), vmax))
    (fast, vf), (gen, vg) = results
    for k in fast:
        close(fast[k], gen[k])
    if mode != G2P_MUSL_MOTION:
        assert vf == pytest.approx(vg, rel=1e-13) and vf > 0
        assert not np.array_equal(fast["F"], before["F"])


def test_reach_past_ghost_layer_is_caught_like_generic(tmp_path):
    sim, st, P = deformed_stepper("cpdi", "none", tmp=tmp_path)
    P.F[7] = np.diag([30.0, 1.0])  # a domain 5 cells long: past the 2-cell ghost layer
    for kern in (KERNELS_2D[st.disc.method], None):
        st.kernels = kern
        st.err[0] = -1
        st._p2g(np.zeros((0, 2)))
        assert st.err[0] == -1 and st.error is not None and "reaches" in st.error
        st.error = None


@pytest.mark.parametrize("jit", [True, False])
def test_cell_of_snaps_like_hat_axis(jit):
    f = cell_of if jit else cell_of.py_func
    # box: base 2, usable cells 2..9 (global)
    assert f(5.25, 2, 2, 9) == (3, 0.25)
    assert f(10.0, 2, 2, 9) == (7, 1.0)                 # on the last usable node: cell below
    assert f(10.0 + 1e-12, 2, 2, 9) == (7, 1.0)         # round-off past it
    assert f(2.0 - 1e-12, 2, 2, 9) == (0, 0.0)          # round-off before the first node
    assert f(1.5, 2, 2, 9)[0] == -1 and f(10.5, 2, 2, 9)[0] == -1
    jlo, jhi = usable_cells(np.array([[-2, 0, 0]]), np.array([8, 8, 1]), np.array([20, 20, 1]))
    assert jlo[0, 0] == 0 and jhi[0, 0] == 4   # nodes 0..5 of a box -2..5


def test_kernels_through_py_func(tmp_path):
    """The CPDI kernels' Python bodies give the compiled results (one occupied patch)."""
    sim, st, P = deformed_stepper("cpdi", 0.025, tmp=tmp_path)
    D = st.disc
    s = int(np.flatnonzero(np.diff(P.start) > 0)[0])
    one = slice(s, s + 1)
    args = (D.lcr, P.start[s:s + 2], D.base[one], D.jlo[one], D.jhi[one], D.nloc,
            D.origin3, D.inv_h3)
    fields = (P.x, P.v, P.F, P.r0, P.mass, P.vol0, P.stress, np.zeros((0, 2)))
    p2g = KERNELS_2D[D.method][0]
    blocks = [grid_block(1, 5, D.layout.n_local_nodes)[0] for _ in range(2)]
    err = np.full(1, -1, np.int64)
    p2g(*args, *fields, blocks[0], err)
    p2g.py_func(*args, *fields, blocks[1], err)
    assert err[0] == -1 and blocks[0][0, 0].sum() > 0
    close(blocks[1], blocks[0], 1e-15)


@pytest.mark.parametrize("method,lcr", CASES)
def test_g2p_locates_the_next_patch_like_locate_patches(method, lcr, tmp_path):
    """The specialised G2P finds each particle's next patch (the pass migration would otherwise
    make): the same ids and moved count as :func:`parmpm.particles.locate_patches` on the new
    positions, with particles pushed across patch boundaries."""
    from parmpm.particles import locate_patches

    sim, st, P = deformed_stepper(method, lcr, tmp=tmp_path)
    st.gnew[:] = 0.0
    st.gnew[:, :, 0] = 40.0   # every particle moves 40 m/s · 1e-3 s = 0.4 cells in x
    st._g2p(G2P_USL, 1e-3)
    first, moved = st._located
    D, lay = st.disc, st.disc.layout
    ref = np.zeros(P.n, np.int64)
    bad, ref_moved = locate_patches(2, P.x, D.origin3, D.inv_h3, lay.cells3, lay.psize3,
                                    lay.patches_per_axis, P.patch, ref)
    assert moved == ref_moved > 0 and first == bad
    np.testing.assert_array_equal(st._new_patch, ref)
