"""Contact's first moments in P2G's own pass (issue 43): the specialised kernels scatter each
field's mass, momentum and force and its first moments ``Σ S m x`` from one support per
particle (``Transfers.p2g_and_moments``), and give the same sums, bit for bit, as P2G followed by
the momentum re-map of the positions (the two passes of before, still MLS's), for every
interpolator with specialised kernels in 2D (cpdi in 3D, whose loop is the 2D one's twin), on a
state as an impact leaves it (the bodies deformed, moving, stressed; APIC's affine fields set).
"""
from __future__ import annotations

import numpy as np
import pytest

from decomposition import SerialComm, accumulate
from parmpm import Simulation
from parmpm.scene.load import scene_from_toml


def pair(dim: int, interpolator: str, transfer: str) -> str:
    """Two disks (spheres) 2 mm apart closing at 2 m/s, with gravity and Coulomb friction."""
    if dim == 2:
        grid = "cell_size = 0.02\ncells = [40, 20]\norigin = [-0.4, -0.2]"
        centres, v = ([-0.151, 0.0], [0.151, 0.0]), ([1.0, 0.2], [-1.0, 0.0])
        shape, g = "disk", [0.0, -9.81]
    else:
        grid = "cell_size = 0.04\ncells = [20, 10, 10]\norigin = [-0.4, -0.2, -0.2]"
        centres, v = ([-0.151, 0.0, 0.0], [0.151, 0.0, 0.0]), ([1.0, 0.2, 0.1], [-1.0, 0.0, 0.0])
        shape, g = "sphere", [0.0, -9.81, 0.0]
    bodies = "".join(f"""
[[bodies]]
shape = "{shape}"
center = {c}
radius = 0.15
material = "rubber"
velocity = {u}
""" for c, u in zip(centres, v))
    return f"""
name = "moments"
dim = {dim}
[grid]
{grid}
[materials.rubber]
model = "neo_hookean"
density = 1000.0
youngs_modulus = 1.0e6
poisson_ratio = 0.3
{bodies}
[method]
interpolator = "{interpolator}"
transfer = "{transfer}"
[gravity]
g = {g}
[contact]
friction = 0.3
[time]
steps = 1
[output]
snapshots = false
figure = false
history = false
"""


#: the interpolators test_contact.py's scenes run with contact (whose kernels they compile)
CASES = [(2, "cpdi", "flip"), (2, "mpm", "flip"), (2, "bspline", "apic"), (2, "cpdi2", "flip"),
         (3, "cpdi", "flip")]


@pytest.mark.parametrize("dim,interpolator,transfer", CASES)
def test_one_pass_gives_the_two_passes_sums(tmp_path, dim, interpolator, transfer):
    sim = Simulation(scene_from_toml(pair(dim, interpolator, transfer)), tmp_path, quiet=True,
                     comm=SerialComm())
    R = sim.particles.rows  # a state mid-impact: deformed, moving, stressed (no step compiled)
    rng = np.random.default_rng(dim)
    R.F[:] += 0.05 * rng.standard_normal(R.F.shape)
    R.v[:] += rng.standard_normal(R.v.shape)
    R.stress[:] = 1e4 * rng.standard_normal(R.stress.shape)
    R.affine[:] = rng.standard_normal(R.affine.shape)
    stepper = sim.state.stepper
    C, T, err = stepper.contact, stepper.transfers, stepper.faults.err
    assert T.kernels is not None and T.kernels.p2g_moments is not None
    assert sim.particles.rows.affine.shape[0] == (sim.particles.n if transfer == "apic" else 0)
    C.split(stepper.P)
    bforce = stepper._body_force(0.0)
    dt = 1e-4  # read by MLS alone, which has no one-pass kernel
    try:
        for k in range(C.K):
            T.subset = C.boxes(k)
            grid, xgrid = C.grids[k], C.moments[k]
            grid.gsum_block[:] = np.nan
            xgrid.gsum_block[:, 1:] = np.nan
            T.p2g(grid, bforce, dt, err, False)
            T.p2g_momentum(xgrid, err, positions=True)
            two = grid.gsum_block.copy(), xgrid.gsum_block.copy()
            grid.gsum_block[:] = np.nan
            xgrid.gsum_block[:, 1:] = np.nan
            T.p2g_and_moments(grid, xgrid, bforce, dt, err, False)
            assert err[0] < 0
            assert np.array_equal(grid.gsum_block, two[0])
            assert np.array_equal(xgrid.gsum_block, two[1])
            assert np.abs(two[1][:, 1:]).sum() > 0.0  # the moments were scattered
    finally:
        T.subset = None


@pytest.mark.parametrize("dim,interpolator,transfer", [(2, "cpdi", "flip"), (3, "cpdi", "flip")])
def test_moments_where_fields_meet_are_the_whole_passes_there(tmp_path, dim, interpolator,
                                                              transfer):
    """Without mirror faces the moments are taken after the masses' accumulation, from the
    patches whose boxes hold a node where fields meet (``ContactPhase.moments_where_fields_meet``):
    at every such node (owned, and the ghost copies the mask marks) they are the whole pass's,
    bit for bit; in 2D fewer particles were visited (the 3D grid is a few patches, all of them
    touched)."""
    sim = Simulation(scene_from_toml(pair(dim, interpolator, transfer)), tmp_path, quiet=True,
                     comm=SerialComm())
    stepper = sim.state.stepper
    C, T, err, plan = stepper.contact, stepper.transfers, stepper.faults.err, stepper.plan
    nodes, eps = stepper.grid_phase.records()[0], stepper.grid_phase.mass_eps
    C.split(stepper.P)
    bforce = stepper._body_force(0.0)
    try:
        for k in range(C.K):
            T.subset = C.boxes(k)
            T.p2g(C.grids[k], bforce, 1e-4, err, False)
            T.p2g_momentum(C.moments[k], err, positions=True)
    finally:
        T.subset = None
    accumulate(plan, *[g.gsum for g in C.grids])
    accumulate(plan, *C.node_views("x"))
    whole = [x.copy() for x in C.node_views("x")]
    C.moments_where_fields_meet(T, nodes, plan, eps, err)
    slots = C.grids[0].gsum_block.shape[0]
    marked = C.mask[:slots, 0, :C.nodes] == 1.0
    assert 0 < marked.sum() < marked.size // 4
    for x, want in zip(C.node_views("x"), whole):
        assert np.array_equal(x[marked], want[marked])
    visited = C.active_boxes(0, marked.any(axis=1))[0][-1]
    assert visited < C.boxes(0)[0][-1] if dim == 2 else visited <= C.boxes(0)[0][-1]
