"""A fixed step's G2P (:mod:`parmpm.transfer.running_speed`): compiled without the wave speed, it
updates every particle exactly as the CFL step's G2P does and reports only whether everything
stayed finite; the stepper measures the CFL speed on its own every few steps, as the independent
pass that sets a run's first step does."""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as hst

from parmpm.core.jit import kernel
from parmpm.materials.passes import max_speed
from parmpm.step.speed_watch import SPEED_EVERY
from parmpm.transfer.running_speed import NO_SPEED, running_speed
from parmpm.transfer.update_order import G2P_MUSL_DEFORM, G2P_USL
from test_specialised_kernels import deformed_stepper, restore, snapshot

#: the kernels whose loops the flag goes through: 2D hat and CPDI, 2D MLS, 3D hat
CASES = [(2, "mpm", "none"), (2, "cpdi", 0.025), (2, "bspline", "mls"), (3, "mpm", "none")]
#: centred supports, which an inverted or huge ``F`` leaves usable (a CPDI domain stops at the
#: support: an error of its own)
CENTRED = [case for case in CASES if case[1] != "cpdi"]


def _g2p(st, P, before, gnew, mode, cfl):
    restore(P, before)
    st.grid.gnew[:] = gnew
    st.transfers.cfl = cfl
    vmax = st.g2p(mode, 1e-4)
    assert st.faults.error is None
    return snapshot(P), vmax


@pytest.mark.parametrize("dim,method,lcr", CASES)
@pytest.mark.parametrize("model", ["neo_hookean", "linear_elastic"])
@pytest.mark.parametrize("mode", [G2P_USL, G2P_MUSL_DEFORM])
def test_a_fixed_step_g2p_updates_every_particle_as_the_cfl_one(dim, method, lcr, model, mode,
                                                               tmp_path):
    sim, st, P = deformed_stepper(dim, method, lcr, model, tmp=tmp_path)
    assert st.transfers.kernels is not None  # the specialised kernels
    rng = np.random.default_rng(5)
    gnew = rng.normal(0.0, 1.0, st.grid.gnew.shape)
    P.dx[:] = rng.normal(0.0, 1e-4, P.dx.shape)
    before = snapshot(P)
    cfl, v_cfl = _g2p(st, P, before, gnew, mode, True)
    fixed, v_fixed = _g2p(st, P, before, gnew, mode, False)
    for k in cfl:
        np.testing.assert_array_equal(fixed[k], cfl[k], err_msg=k)
    assert not np.array_equal(cfl["F"], before["F"])
    assert v_fixed == 0.0
    # the CFL G2P's speed is what the pass of its own measures on the updated particles
    assert v_cfl == pytest.approx(max_speed(dim, P.v, P.F, P.mat, st.params), rel=1e-12)
    assert v_cfl > 0


@pytest.mark.parametrize("dim,method,lcr", CENTRED)
@pytest.mark.parametrize("spoil", ["inverted", "nan_velocity", "inf_stress"])
def test_a_fixed_step_g2p_stops_where_the_cfl_one_does(dim, method, lcr, spoil, tmp_path):
    """An inverted particle (``c = inf`` in the CFL G2P, for both laws), a NaN grid velocity or
    a deformation whose stress overflows: both report ``inf``."""
    sim, st, P = deformed_stepper(dim, method, lcr, "linear_elastic", tmp=tmp_path)
    gnew = np.zeros(st.grid.gnew.shape)
    k = P.n // 2
    if spoil == "inverted":
        P.F[k] = np.diag([-1.0] + [1.0] * (dim - 1))
    elif spoil == "inf_stress":
        P.F[k] = np.eye(dim) * 1e306
    before = snapshot(P)
    if spoil == "nan_velocity":
        gnew[...] = np.nan
    for cfl in (True, False):
        restore(P, before)
        st.grid.gnew[:] = gnew
        st.transfers.cfl = cfl
        assert st.g2p(G2P_USL, 1e-4) == math.inf, (cfl, spoil)


def test_the_stepper_measures_a_fixed_steps_speed_every_few_steps(tmp_path):
    """After :meth:`Stepper.fix_step`: measured at the first step and every ``SPEED_EVERY``
    after it, with the speed of the pass of its own; in between G2P's 0."""
    sim, st, P = deformed_stepper(2, "mpm", "none", tmp=tmp_path)
    P.F[:] = np.eye(2)
    P.stress[:] = 0.0
    g = np.array([0.0, -9.81, 0.0])
    st.fix_step()
    seen = []
    for n in range(SPEED_EVERY + 2):
        vmax = st.step(1e-5, g, n * 1e-5)
        seen.append(st.speed_measured)
        if st.speed_measured:  # the pass of its own against the dimension-generic one
            assert vmax == pytest.approx(max_speed(2, P.v, P.F, P.mat, st.params), rel=1e-12)
            assert vmax > 0
        else:
            assert vmax == 0.0
    assert seen == [True] + [False] * (SPEED_EVERY - 1) + [True, False]


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("model", ["neo_hookean", "linear_elastic"])
def test_the_speed_pass_is_the_dimension_generic_one(dim, model, tmp_path):
    """The 2D/3D pass a fixed step measures with (G2P's formula) against the dimension-generic
    pass that sets a run's first step, on deformed particles; an inverted one makes both
    ``inf``."""
    from parmpm.transfer.kernels2d.material import speed_pass as pass_2d
    from parmpm.transfer.kernels3d.material import speed_pass as pass_3d

    sim, st, P = deformed_stepper(dim, "mpm", "none", model, tmp=tmp_path)
    fast = (pass_2d if dim == 2 else pass_3d)(P.v, P.F, P.mat, st.params)
    assert fast == pytest.approx(max_speed(dim, P.v, P.F, P.mat, st.params), rel=1e-12)
    assert fast > 0
    P.F[P.n // 3] = np.diag([-1.0] + [1.0] * (dim - 1))
    assert (pass_2d if dim == 2 else pass_3d)(P.v, P.F, P.mat, st.params) == math.inf
    assert max_speed(dim, P.v, P.F, P.mat, st.params) == math.inf


@kernel
def _running_max(c2, v2):
    run = NO_SPEED
    for i in range(c2.size):
        run = running_speed(True, run, c2[i], v2[i], 0.0, 1.0)
    return run[0]


def _largest_by_hand(c2, v2) -> float:
    """Every particle's ``√c² + √v²``, the largest (``inf`` once one is NaN): the definition."""
    vmax = 0.0
    for a, b in zip(c2.tolist(), v2.tolist()):
        s = math.sqrt(a) + math.sqrt(b) if a >= 0 and b >= 0 else math.nan
        vmax = math.inf if s != s else max(vmax, s)
    return vmax


# a few values, so that particles tie and dominate each other in every way
_SQUARES = hst.sampled_from([0.0, 1e-300, 0.25, 1.0, np.nextafter(1.0, 2.0), 2.0, 1296.0,
                            np.nextafter(1296.0, 0.0), 1e300, math.inf, math.nan])


@settings(max_examples=300, deadline=None)
@given(hst.lists(hst.tuples(_SQUARES, _SQUARES), min_size=1, max_size=40))
def test_the_running_speed_skips_only_particles_that_cannot_raise_it(pairs):
    """The skip of a particle whose ``c²`` and ``v²`` are both at most those of the particle that
    set the maximum (no square root taken) leaves the result bit for bit the largest
    ``√c² + √v²`` over every particle, ``inf`` once one is NaN."""
    c2 = np.array([p[0] for p in pairs])
    v2 = np.array([p[1] for p in pairs])
    assert _running_max(c2, v2) == _largest_by_hand(c2, v2)


def test_the_running_speed_on_many_near_equal_particles():
    """Particles alike to the last bits (a block in uniform motion, the benchmark's), and the
    same with a spread: the largest speed bit for bit."""
    rng = np.random.default_rng(11)
    for spread in (1e-15, 1e-3, 1.0):
        c2 = 1296.0 * (1.0 + spread * rng.random(10_000))
        v2 = 1.25 * (1.0 + spread * rng.random(10_000))
        assert _running_max(c2, v2) == _largest_by_hand(c2, v2)
