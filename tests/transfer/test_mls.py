"""MLS-MPM transfers (``method.transfer = "mls"``, :mod:`parmpm.transfer.affine`) at the kernel level, on
the 2D and 3D specialised kernels and the dimension-generic ones (1D and the reference): the MLS
velocity gradient is exact for an affine grid velocity, and P2G folds exactly ``Δt f`` into the
momentum. Angular momentum, the energy account, checkpoints and rank independence are in
``test_apic.py``; specialised against generic on random states in ``test_specialised_kernels.py``.
"""
import numpy as np
import pytest

from parmpm.transfer.update_order import G2P_USL
from test_specialised_kernels import deformed_stepper

#: (dimension, kernels): specialised MLS kernels in 2D and 3D, the generic ones in every dimension
KINDS = [(2, "specialised"), (2, "generic"), (3, "specialised"), (3, "generic")]


def _node_positions(st):
    """(slots, nodes, d) positions of every node of every patch slot's box (ghosts included)."""
    D = st.disc
    d = D.dim
    nloc = np.asarray(D.nloc)
    loc = np.arange(st.grid.gnew.shape[1])
    idx = np.stack([loc % nloc[0], (loc // nloc[0]) % nloc[1], loc // (nloc[0] * nloc[1])], 1)
    glob = D.base[:, None, :] + idx[None, :, :]
    return (np.asarray(D.origin3)[None, None, :] + glob * np.asarray(D.h3)[None, None, :])[..., :d]


@pytest.mark.parametrize("dim,kind", KINDS)
def test_the_mls_gradient_is_exact_for_an_affine_grid_velocity(dim, kind, tmp_path):
    """``v_i = A x_i + b`` on every node: G2P gives ``C_p = L_p = A`` and ``v_p = A x_p + b``
    (``Σ φ r ⊗ r = D`` and ``Σ φ r = 0``), so ``F ← (I + Δt A) F`` and ``x ← x + Δt v``.
    (The gradient-weight sum of APIC is exact here too: this checks MLS's own path.)"""
    sim, st, P = deformed_stepper(dim, "bspline", "mls", tmp=tmp_path)
    st.use_kernels(kind)
    assert (st.transfers.kernels is None) == (kind == "generic")
    rng = np.random.default_rng(5)
    A, b = rng.normal(0.0, 2.0, (dim, dim)), rng.normal(0.0, 1.0, dim)
    xn = _node_positions(st)
    st.grid.gnew[:] = 0.0
    st.grid.gnew[:, :, :dim] = xn @ A.T + b
    x0, F0 = P.x.copy(), P.F.copy()
    dt = 1e-4
    st.g2p(G2P_USL, dt)
    assert st.faults.error is None
    scale = np.abs(A).max() * np.abs(xn).max()
    np.testing.assert_allclose(P.affine, np.broadcast_to(A, P.affine.shape), rtol=0,
                               atol=1e-12 * scale)
    np.testing.assert_allclose(P.v, x0 @ A.T + b, rtol=0, atol=1e-13 * scale)
    np.testing.assert_allclose(P.x, x0 + dt * P.v, rtol=0, atol=1e-15 * np.abs(x0).max())
    np.testing.assert_allclose(P.F, (np.eye(dim) + dt * A) @ F0, rtol=0, atol=1e-13)


@pytest.mark.parametrize("dim,kind", KINDS)
@pytest.mark.parametrize("forced", [False, True])
def test_p2g_folds_dt_times_the_force_into_the_momentum(dim, kind, forced, tmp_path):
    """With the energy ledger on (the force rows written), the momentum of a step ``Δt`` is the
    momentum of ``Δt = 0`` plus ``Δt f``, body force included; the mass does not depend on Δt."""
    sim, st, P = deformed_stepper(dim, "bspline", "mls", tmp=tmp_path)
    st.use_kernels(kind)
    st.ledger = sim.state.energy.ledger
    bforce = (np.random.default_rng(6).normal(0, 5.0, (P.n, dim)) if forced
              else np.zeros((0, dim)))
    st.p2g(bforce, 0.0)
    m0, mv0, f0 = st.grid.gm.copy(), st.grid.gmv.copy(), st.grid.gf.copy()
    dt = 1e-3
    st.p2g(bforce, dt)
    assert st.faults.error is None and np.abs(f0).max() > 0
    np.testing.assert_array_equal(st.grid.gm, m0)
    np.testing.assert_array_equal(st.grid.gf, f0)
    scale = np.abs(mv0).max() + dt * np.abs(f0).max()
    np.testing.assert_allclose(st.grid.gmv, mv0 + dt * f0, rtol=0, atol=1e-13 * scale)
    assert np.abs(st.grid.gmv - mv0).max() > 1e-6 * scale  # the force is there to be folded


def test_one_particle_per_cell_under_mls_is_warned_about():
    """MLS at one particle per cell diverged on the manufactured solution (docs/mls.md): the
    set-up says so for each such body, and only under MLS."""
    from parmpm.driver.set_up import sparse_mls_warnings
    from parmpm.scene.load import load_scene

    over = ["method.interpolator=bspline", "boundary.regions_with_splines=true", "bodies.0.ppc=[1, 2]"]
    lines = sparse_mls_warnings(load_scene("hanging_bar", over + ["method.transfer=mls"]).spec)
    assert len(lines) == 1 and lines[0].startswith("bodies.0.ppc = [1, 2] with method.transfer")
    assert sparse_mls_warnings(load_scene("hanging_bar", over + ["method.transfer=apic"]).spec) == []
    assert sparse_mls_warnings(load_scene("hanging_bar", ["method.interpolator=bspline", "boundary.regions_with_splines=true",
                                                          "method.transfer=mls"]).spec) == []


def test_the_energy_ledger_does_not_change_an_mls_run(tmp_path):
    """With a history the MLS P2G also writes the force rows (for the ledger), without one it
    skips them and the step zeroes, folds and exchanges fewer rows: the motion must be the same
    bits either way (manufactured solution: body force and mirror faces)."""
    from parmpm.scene.load import load_scene
    from parmpm.driver.simulation import Simulation

    over = ["method.interpolator=bspline", "boundary.regions_with_splines=true", "method.transfer=mls", "time.steps=20",
            "output.snapshots=false", "output.figure=false"]
    states = []
    for k, history in enumerate(("true", "false")):
        sim = Simulation(load_scene("manufactured", over + [f"output.history={history}"]),
                         tmp_path / str(k), quiet=True)
        sim.run()
        assert (sim.state.stepper.ledger is not None) == (history == "true")
        P = sim.particles
        o = np.argsort(P.gid)
        states.append({f: getattr(P, f)[o].copy() for f in ("x", "v", "F", "affine")})
    for f in states[0]:
        np.testing.assert_array_equal(states[0][f], states[1][f], err_msg=f)
