"""The separation count's nodes through the 2D and 3D CPDI walks of the step's own corners
(:mod:`parmpm.transfer.kernels2d.support_nodes`, :mod:`parmpm.transfer.kernels3d.support_nodes`)
against the dimension-generic walk
(:func:`parmpm.transfer.generic.support_nodes`, whose weights are the generic support's): the
same nodes in the same order, the same counts and the same reach error, array for array, on
randomly deformed domains with and without the ``l_cr`` cap, on corners exactly on grid lines
(a zero fraction: the node across has weight 0 and is not listed) and on a particle past the
ghost layer. Both walks also run as ``.py_func`` on a few particles (readable failures)."""
import numpy as np
import pytest

from parmpm.driver import measures
from parmpm.step.transfers import SUPPORT_NODES
from test_specialised_kernels import LCR, deformed_stepper

DIMS = [2, 3]
#: a particle's corners in one cell, in two, and in the 2^d cells around a node: each case met
COUNTS = {2: {4, 6, 9}, 3: {8, 12, 27}}


def _walk(st, kind):
    """(nodes, count, err) of every particle through the ``kind`` kernels; unused entries keep a
    marker, so the arrays compare whole."""
    P = st.P
    P.compact()
    nodes = np.full((P.n, 4 ** st.disc.dim), -7, np.int64)  # 2^d corners x 2^d nodes
    count = np.zeros(P.n, np.int64)
    err = np.full(2, -1, np.int64)
    st.use_kernels(kind)
    try:
        st.transfers.support_nodes(nodes, count, err)
    finally:
        st.use_kernels("specialised")
    return nodes, count, err


def _same_walks(st):
    fast, generic = _walk(st, "specialised"), _walk(st, "generic")
    for a, b in zip(fast, generic):
        np.testing.assert_array_equal(a, b)
    return fast


@pytest.mark.parametrize("dim", DIMS)
@pytest.mark.parametrize("scaled", [False, True])
def test_deformed_domains_list_the_generic_nodes(dim, scaled, tmp_path):
    _, st, P = deformed_stepper(dim, "cpdi", LCR[dim] if scaled else "none", tmp=tmp_path)
    nodes, count, err = _same_walks(st)
    assert err[0] == -1
    assert COUNTS[dim] <= set(count.tolist())
    # each node once, every id inside the grid
    total = int(np.prod(st.disc.nglob[:dim]))
    for i in range(P.n):
        row = nodes[i, :count[i]]
        assert np.unique(row).size == row.size
        assert row.min() >= 0 and row.max() < total


@pytest.mark.parametrize("dim", DIMS)
def test_corners_on_grid_lines_drop_the_zero_weight_nodes(dim, tmp_path):
    """Undeformed domains one cell wide centred half a cell from a node: corners land on grid
    lines (in floating point some exactly, some a rounding away), so a corner's zero fraction
    gives the node across it weight 0, and the walks must drop the same ones."""
    _, st, P = deformed_stepper(dim, "cpdi", "none", tmp=tmp_path)
    D = st.disc
    o, ih = D.origin3[:dim], D.inv_h3[:dim]
    h = 1.0 / ih
    P.x[:] = o + (np.floor((P.x - o) * ih) + 0.5) * h
    P.F[:] = np.eye(dim)
    P.r0[:] = 0.0
    for k in range(dim):
        P.r0[:, k, k] = 0.5 * h[k]
    nodes, count, err = _same_walks(st)
    # the kernels' arithmetic, in numpy: the low corners' grid coordinate along x
    low = (P.x[:, 0] - o[0]) * ih[0] - 0.5 * h[0] * ih[0]
    assert np.any(low == np.trunc(low)), "no corner landed exactly on a grid line"
    assert err[0] == -1 and count.min() >= 2 ** dim
    # a domain one cell wide whose corners sit on nodes touches 2^d nodes, not 3^d
    assert np.any(count == 2 ** dim)


@pytest.mark.parametrize("dim", DIMS)
def test_reach_past_the_ghost_layer_is_noted_alike(dim, tmp_path):
    _, st, P = deformed_stepper(dim, "cpdi", "none", tmp=tmp_path)
    P.F[7] = np.diag([30.0] + [1.0] * (dim - 1))  # 5 cells long: past the 2-cell ghost layer
    nodes, count, err = _same_walks(st)
    P.compact()
    assert err[1] == -1 and err[0] >= 0 and count[err[0]] == 0


@pytest.mark.parametrize("dim", DIMS)
def test_py_func_walk_matches(dim, tmp_path):
    """The walk's Python body on the slots up to the first that holds particles gives the
    compiled walk's rows."""
    _, st, P = deformed_stepper(dim, "cpdi", LCR[dim], tmp=tmp_path)
    P.compact()
    how, boxes, fields = st.transfers.records()
    first = int(np.flatnonzero(np.diff(boxes.start))[0])
    boxes = boxes._replace(start=boxes.start[:first + 2])
    out = []
    for walk in (SUPPORT_NODES[dim], SUPPORT_NODES[dim].py_func):
        nodes = np.full((P.n, 4 ** dim), -7, np.int64)
        count = np.zeros(P.n, np.int64)
        err = np.full(2, -1, np.int64)
        walk(how.lcr, boxes, boxes.order, fields, nodes, count, err)
        out.append((nodes, count, err))
    assert out[0][1].sum() > 0
    for a, b in zip(*out):
        np.testing.assert_array_equal(a, b)


@pytest.mark.parametrize("dim", DIMS)
def test_measures_counts_one_piece_of_an_intact_body(dim, tmp_path):
    """``measures.components`` on a rank's state (through ``Transfers.support_nodes``, the walk
    where the specialised kernels run) counts one piece for the intact body."""
    sim, _, _ = deformed_stepper(dim, "cpdi", LCR[dim], tmp=tmp_path)
    assert measures.components(sim.state) == 1
