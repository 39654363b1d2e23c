"""Contact's first moments ``Σ S m x`` (issue 43): without mirror faces they are taken after
the masses' accumulation, from the patches whose boxes hold a node where fields meet, and are
the whole pass's at every such node, bit for bit. (A one-pass P2G-and-moments kernel per
interpolator was dropped: only mirror-face contact scenes used it, its two-pass equivalent gave
the same bits, and its six variants cost a fresh clone's tests 78 s of compiling.)
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
