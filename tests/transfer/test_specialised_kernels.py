"""The hand-specialised kernels (:mod:`parmpm.transfer.kernels2d`, :mod:`parmpm.transfer.kernels3d`) against the
dimension-generic ones (:mod:`parmpm.transfer.generic`), for every entry of the kernel registry
(:data:`parmpm.step.transfers.SPECIALISED`, and the MLS kernels of :data:`parmpm.step.transfers.SPECIALISED_MLS`)
in 2D and 3D.

On the hanging bar with several patches and a randomly deformed, moving, stressed particle state,
P2G sums, the MUSL momentum re-map and every G2P mode (positions, velocities, F, stress, the CFL
speed) agree to round-off, with and without domain scaling (an ``l_cr`` that caps some but not
all domains), body forces and every registered material law; the stress pass agrees; a support
past the ghost layer is caught the same way; G2P finds each particle's next patch as
:func:`parmpm.particles.locate.locate_patches` does. The kernels switch through
:meth:`parmpm.step.stepper.Stepper.use_kernels` (never by their positional signatures); every kernel
also runs through ``.py_func`` (readable failures, coverage).
"""
import numpy as np
import pytest

import parmpm
from parmpm.transfer.kernels2d.cells import cell_of, usable_cells
from parmpm.transfer.kernels2d.material import stress_pass as stress_pass_2d
from parmpm.transfer.kernels3d.cells import cells_of8
from parmpm.transfer.kernels3d.material import stress_pass as stress_pass_3d
from parmpm.materials import MODELS
from parmpm.particles.locate import locate_patches
from parmpm.shapes import BSPLINE, CPDI, CPDI2, INTERPOLATORS
from parmpm.shapes.cpdi2 import affine_corners
from parmpm.driver.simulation import Simulation
from parmpm.step.transfers import SPECIALISED, SPECIALISED_MLS
from parmpm.materials.passes import stress_pass as generic_stress_pass
from parmpm.transfer.update_order import G2P_MUSL_DEFORM, G2P_MUSL_MOTION, G2P_USL

QUIET = ["output.snapshots=false", "output.figure=false", "time.steps=1"]
SCENE = {2: "hanging_bar", 3: "hanging_bar_3d"}
#: an l_cr (m) below most deformed corner lengths (2D: Δx = 0.05 m; 3D: Δx = 0.2 m, 3 ppc)
LCR = {2: 0.025, 3: 0.07}
NAME = {i.code: name for name, i in INTERPOLATORS.items()}
MODES = [G2P_USL, G2P_MUSL_MOTION, G2P_MUSL_DEFORM]


def _cases():
    """(dim, interpolator name, l_cr) for every registered specialised kernel; for bspline the
    "l_cr" ``"apic"`` means APIC transfers (its kernels read the affine field), ``"mls"`` MLS
    (kernels of their own)."""
    out = []
    for dim, kernels in sorted(SPECIALISED.items()):
        for code in sorted(kernels):
            spline = ["none", "apic"] + (["mls"] if dim in SPECIALISED_MLS else [])
            lcrs = (["none", LCR[dim]] if code in (CPDI, CPDI2) else
                    spline if code == BSPLINE else ["none"])
            out += [pytest.param(dim, NAME[code], lcr, id=f"{dim}d-{NAME[code]}-lcr={lcr}")
                    for lcr in lcrs]
    return out


CASES = _cases()
DIMS = sorted(SPECIALISED)


def _deformation(rng, n, dim):
    """``F = Q U``: a rotation times a stretch/shear near 1."""
    if dim == 2:
        th = rng.uniform(-0.4, 0.4, n)
        c, s = np.cos(th), np.sin(th)
        Q = np.stack([np.stack([c, -s], 1), np.stack([s, c], 1)], 1)
        U = np.zeros((n, 2, 2))
        U[:, 0, 0], U[:, 1, 1] = rng.uniform(0.8, 1.6, n), rng.uniform(0.8, 1.6, n)
        U[:, 0, 1] = rng.uniform(-0.2, 0.2, n)
        return Q @ U
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
    return Q @ U


def deformed_stepper(dim, method, lcr, model="neo_hookean", seed=1, tmp=None):
    """A stepper on the hanging bar (patches of 4 cells) whose particles have random velocities,
    deformation gradients and symmetric stresses."""
    over = QUIET + [f'method.interpolator="{method}"', "grid.patch_size=4",
                    f'materials.bar.model="{model}"']
    if method in ("cpdi", "cpdi2"):
        over.append(f"method.lcr={lcr}")
    if method == "bspline":  # the bar's held region: kernels only, no physics judged
        over.append("boundary.regions_with_splines=true")
    if lcr in ("apic", "mls"):
        over.append(f"method.transfer={lcr}")
    sim = Simulation(parmpm.load_scene(SCENE[dim], over), tmp, quiet=True)
    st, P = sim.state.stepper, sim.state.stepper.P
    rng = np.random.default_rng(seed)
    P.F[:] = _deformation(rng, P.n, dim)
    P.v[:] = rng.normal(0.0, 1.0, (P.n, dim))
    P.affine[:] = rng.normal(0.0, 10.0, P.affine.shape)  # no rows under FLIP
    if P.corners.shape[0]:  # cpdi2: the deformed domains, each corner moved off the parallelogram
        P.corners[:] = affine_corners(P.F, P.r0) + rng.normal(0.0, 0.1, P.corners.shape) * np.abs(
            P.r0).max()
    S = rng.normal(0.0, 1e4, (P.n, dim, dim))
    P.stress[:] = S + S.transpose(0, 2, 1)
    return sim, st, P


def snapshot(P):
    return {k: getattr(P, k).copy() for k in ("x", "v", "F", "stress", "dx", "affine", "corners")}


def restore(P, snap):
    for k, a in snap.items():
        getattr(P, k)[:] = a


def close(a, b, rtol=1e-12):
    scale = max(1.0, float(np.max(np.abs(b), initial=0.0)))
    np.testing.assert_allclose(a, b, rtol=0, atol=rtol * scale)


def _registered(dim, st):
    """The kernels the stepper should have picked."""
    return SPECIALISED_MLS[dim] if st.mls else SPECIALISED[dim][st.disc.method]


def test_registry_names_registered_interpolators():
    assert DIMS == [2, 3]
    for kernels in SPECIALISED.values():
        for code, three in kernels.items():  # p2g, p2g_momentum, g2p
            assert code in NAME and len(three) == 3 and all(callable(k) for k in three)


@pytest.mark.parametrize("dim", DIMS)
def test_lcr_engages_on_some_domains(dim, tmp_path):
    sim, st, P = deformed_stepper(dim, "cpdi", LCR[dim], tmp=tmp_path)
    scaled = parmpm.domain_vectors(dim, CPDI, LCR[dim], P.F, P.r0, P.lh0)
    free = parmpm.domain_vectors(dim, CPDI, None, P.F, P.r0, P.lh0)
    changed = np.any(scaled != free, axis=(1, 2))
    assert 0.2 < changed.mean() < 0.95


@pytest.mark.parametrize("dim,method,lcr", CASES)
@pytest.mark.parametrize("forced", [False, True])
def test_p2g_matches_generic(dim, method, lcr, forced, tmp_path):
    sim, st, P = deformed_stepper(dim, method, lcr, tmp=tmp_path)
    assert st.transfers.kernels is _registered(dim, st)
    bforce = (np.random.default_rng(2).normal(0, 5.0, (P.n, dim)) if forced
              else np.zeros((0, dim)))
    dt = 1e-4
    if st.mls:  # its force rows are written for the energy ledger alone
        st.p2g(bforce, dt)
        assert not np.any(st.grid.gf) and np.any(st.grid.gmv)
        st.ledger = sim.state.energy.ledger
    st.p2g(bforce, dt)
    fast = st.grid.gsum.copy()
    st.use_kernels("generic")
    assert st.transfers.kernels is None
    st.p2g(bforce, dt)
    assert np.max(st.grid.gsum[:, :, 0]) > 0 and st.faults.error is None
    close(fast, st.grid.gsum)
    st.use_kernels("specialised")
    st.p2g_momentum()
    fast_mv = st.grid.gmv.copy()
    st.grid.gsum[:] = 0.0
    st.use_kernels("generic")
    st.p2g_momentum()
    close(fast_mv, st.grid.gmv)


@pytest.mark.parametrize("dim,method,lcr", CASES)
@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("model", sorted(MODELS))
def test_g2p_matches_generic(dim, method, lcr, mode, model, tmp_path):
    sim, st, P = deformed_stepper(dim, method, lcr, model, tmp=tmp_path)
    rng = np.random.default_rng(3)
    st.grid.gnew[:] = rng.normal(0.0, 1.0, st.grid.gnew.shape)
    P.dx[:] = rng.normal(0.0, 1e-4, P.dx.shape)
    before = snapshot(P)
    dt, results = 1e-4, []
    for kind in ("specialised", "generic"):
        restore(P, before)
        st.use_kernels(kind)
        vmax = st.g2p(mode, dt)
        assert st.faults.error is None
        results.append((snapshot(P), vmax))
    (fast, vf), (gen, vg) = results
    for k in fast:
        close(fast[k], gen[k])
    if mode != G2P_MUSL_MOTION:
        assert vf == pytest.approx(vg, rel=1e-13) and vf > 0
        assert not np.array_equal(fast["F"], before["F"])


@pytest.mark.parametrize("dim", DIMS)
@pytest.mark.parametrize("model", sorted(MODELS))
def test_stress_pass_matches_generic(dim, model, tmp_path):
    sim, st, P = deformed_stepper(dim, "mpm", "none", model, tmp=tmp_path)
    fast, gen = np.empty_like(P.stress), np.empty_like(P.stress)
    cf = (stress_pass_2d if dim == 2 else stress_pass_3d)(P.F, P.mat, st.params, fast)
    cg = generic_stress_pass(dim, P.F, P.mat, st.params, P.damage, gen)
    close(fast, gen)
    assert cf == pytest.approx(cg, rel=1e-13)


@pytest.mark.parametrize("dim", DIMS)
def test_reach_past_ghost_layer_is_caught_like_generic(dim, tmp_path):
    sim, st, P = deformed_stepper(dim, "cpdi", "none", tmp=tmp_path)
    P.F[7] = np.diag([30.0] + [1.0] * (dim - 1))  # 5 cells long: past the 2-cell ghost layer
    for kind in ("specialised", "generic"):
        st.use_kernels(kind)
        st.faults.err[0] = -1
        st.p2g(np.zeros((0, dim)), 1e-4)
        assert st.faults.err[0] == -1 and st.faults.error is not None and "reaches" in st.faults.error
        assert f"particle {P.gid[7]} " in st.faults.error
        st.faults.error = None
        st.g2p(G2P_USL, 1e-4)
        st._check("g2p")
        assert st.faults.error is not None and f"particle {P.gid[7]} " in st.faults.error
        st.faults.error = None


def test_use_kernels_refuses_an_unknown_kind(tmp_path):
    sim, st, P = deformed_stepper(2, "mpm", "none", tmp=tmp_path)
    with pytest.raises(ValueError, match="specialised"):
        st.use_kernels("fast")


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


@pytest.mark.parametrize("dim,method,lcr", CASES)
def test_kernels_through_py_func(dim, method, lcr, tmp_path, monkeypatch):
    """The kernels' Python bodies (``.py_func``, put in the registry) give the compiled results:
    P2G sums, the momentum re-map, and G2P's particles, speed and next patches."""
    sim, st, P = deformed_stepper(dim, method, lcr, tmp=tmp_path)
    registry, key = (SPECIALISED_MLS, dim) if st.mls else (SPECIALISED[dim], st.disc.method)
    compiled = registry[key]
    rng = np.random.default_rng(4)
    gnew = rng.normal(0.0, 1.0, st.grid.gnew.shape)
    before, out = snapshot(P), []
    for kernels in (compiled, type(compiled)(*(k and k.py_func for k in compiled))):
        monkeypatch.setitem(registry, key, kernels)
        st.use_kernels("specialised")
        assert st.transfers.kernels is kernels
        restore(P, before)
        st.faults.err[0] = -1
        st.p2g(np.zeros((0, dim)), 1e-4)
        sums = st.grid.gsum.copy()
        st.p2g_momentum()
        momentum = st.grid.gmv.copy()
        st.grid.gnew[:] = gnew
        vmax = st.g2p(G2P_USL, 1e-4)
        assert st.faults.err[0] == -1 and st.faults.error is None
        out.append((sums, momentum, snapshot(P), vmax, st.moves.located, st.moves.new_patch.copy()))
    (s0, m0, p0, v0, l0, n0), (s1, m1, p1, v1, l1, n1) = out
    assert s0[:, :, 0].sum() > 0
    close(s1, s0, 1e-15)
    close(m1, m0, 1e-15)
    for k in before:
        close(p1[k], p0[k], 1e-15)
    assert v1 == v0 > 0 and l1 == l0
    np.testing.assert_array_equal(n1, n0)


@pytest.mark.parametrize("dim,method,lcr", CASES)
def test_g2p_locates_the_next_patch_like_locate_patches(dim, method, lcr, tmp_path):
    """The specialised G2P finds each particle's next patch (the pass migration would otherwise
    make): the same ids and moved count as :func:`locate_patches` on the new positions, with
    particles pushed across patch boundaries."""
    sim, st, P = deformed_stepper(dim, method, lcr, tmp=tmp_path)
    st.grid.gnew[:] = 0.0
    h = st.disc.h[0]
    st.grid.gnew[:, :, 0] = 0.4 * h / 1e-3   # every particle moves 0.4 cells in x
    st.g2p(G2P_USL, 1e-3)
    first, moved = st.moves.located
    D, lay = st.disc, st.disc.layout
    ref = np.zeros(P.n, np.int64)
    bad, ref_moved = locate_patches(dim, P.x, D.origin3, D.inv_h3, lay.cells3, lay.psize3,
                                    lay.patches_per_axis, P.patch, ref)
    assert moved == ref_moved > 0 and first == bad
    np.testing.assert_array_equal(st.moves.new_patch, ref)
