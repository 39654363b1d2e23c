"""The transfer kernels' shared particle loops and the one walk over a CPDI corner's cell.

The 2D and 3D kernels are each interpolator's numba functions (``support``, ``scatter``,
``gather``, ``follow``) run by one loop per dimension (:mod:`parmpm.transfer.kernels2d.loops`,
:mod:`parmpm.transfer.kernels3d.loops`), which visits rows through
:func:`parmpm.transfer.rows.row`. The kernels' sums are checked against the generic kernels in
``test_specialised_kernels.py``, and bit for bit against the hand-written loops they replaced by
``run_scripts/tools/bit_identical.py``; here: the loops' contract with their hooks (canonical order,
a failed support noted and skipped, the None order), that the loop and its hooks leave no call
behind in the machine code (LLVM inlines them: :mod:`parmpm.core.jit`), that
every kernel is a module-level function numba caches (a kernel factory's closure is not: numba
keys its cache to a pickle of the closure's cells, new in every process), and that
:func:`parmpm.shapes.cpdi.cell_node` walks a cell's nodes as the nested loops it replaced did.
"""
from collections import namedtuple

import numpy as np
import pytest
from numba import njit

from parmpm.core.cache_key import is_keyed
from parmpm.core.jit import helper_kernel
from parmpm.core.records import Boxes
from parmpm.shapes.cpdi import cell_node
from parmpm.transfer.kernels2d import KERNELS_2D, MLS_KERNELS_2D
from parmpm.transfer.kernels2d.loops import each_particle as each_particle_2d
from parmpm.transfer.kernels3d import KERNELS_3D, MLS_KERNELS_3D
from parmpm.transfer.kernels3d.loops import each_particle as each_particle_3d
from parmpm.transfer.rows import row


@helper_kernel
def _support(i, frame, slot, shape, fields):
    """Out of reach (−2) for a negative ``x``; the stencil is ``shape · x``."""
    x = fields[0]
    return (-2 if x[i] < 0.0 else 0), (shape * x[i],)


#: what the walks read and write, as the kernels' :class:`parmpm.core.records.Fields` (``sides``
#: None: no crack faces)
Walked = namedtuple("Walked", ("x", "seen", "count", "sides"))


@helper_kernel
def _scatter(i, g, frame, st, fields, args):
    """Record the visit (in ``fields``: what a hook writes is a kernel argument) and add the
    stencil to the slot's first grid value."""
    seen, count = fields.seen, fields.count
    seen[count[0]] = i
    count[0] += 1
    g[0, 0] += st[0]


@helper_kernel
def _scatter_2d(i, g, frame, st, fields, args, side):
    """:func:`_scatter` as a 2D hook (``side``: the slot's crack faces, None here)."""
    _scatter(i, g, frame, st, fields, args)


@njit
def _walk_2d(boxes, order, grid, err, fields):
    each_particle_2d(_support, _scatter_2d, boxes, order, grid, err, 2.0, fields, None)


@njit
def _walk_3d(boxes, order, grid, err, fields):
    each_particle_3d(_support, _scatter, boxes, order, grid, err, 2.0, fields, None)


@njit
def _rows(order, n):
    out = np.empty(n, np.int64)
    for kk in range(np.uint64(0), np.uint64(n)):
        out[kk] = row(order, kk)
    return out


def _boxes(start, d):
    slots = len(start) - 1
    box = np.zeros((slots, 3), np.int64)
    return Boxes(np.asarray(start, np.int64), None, box, box, box + 1, np.full(3, 4, np.int64),
                 np.full(3, 4, np.int64), np.zeros(3), np.ones(3))


def test_row_is_the_canonical_position_without_an_order_and_the_order_with_one():
    order = np.array([3, 1, 0, 2])
    assert _rows(None, 4).tolist() == [0, 1, 2, 3]
    assert _rows(order, 4).tolist() == [3, 1, 0, 2]
    assert [row(None, k) for k in range(4)] == [0, 1, 2, 3]
    assert [row(order, k) for k in range(4)] == [3, 1, 0, 2]


@pytest.mark.parametrize("walk,d", [(_walk_2d, 2), (_walk_3d, 3)])
@pytest.mark.parametrize("ordered", [False, True])
def test_each_particle_visits_the_slots_in_canonical_order_and_skips_failed_supports(walk, d,
                                                                                     ordered):
    start = [0, 3, 3, 7]  # an empty slot in the middle
    x = np.array([1.0, 2.0, -1.0, 4.0, 5.0, -6.0, 7.0])
    order = np.array([6, 0, 2, 5, 1, 4, 3]) if ordered else None
    rows = order if ordered else np.arange(7)
    grid = np.zeros((3, 1, 1))
    err = np.full(2, -1, np.int64)
    seen, count = np.full(7, -1, np.int64), np.zeros(1, np.int64)
    walk(_boxes(start, d), order, grid, err, Walked(x, seen, count, None))
    visited = [int(r) for r in rows if x[r] >= 0.0]
    assert seen[:count[0]].tolist() == visited
    first_bad = next(int(r) for r in rows if x[r] < 0.0)
    assert err.tolist() == [first_bad, -2]
    for p in range(3):
        own = [r for r in rows[start[p]:start[p + 1]] if x[r] >= 0.0]
        assert grid[p, 0, 0] == sum(2.0 * x[r] for r in own)


@pytest.mark.parametrize("d", [2, 3])
def test_the_loop_and_its_hooks_are_inlined_into_the_kernel(d):
    """The optimised LLVM IR of a kernel running the loop calls neither the loop nor a hook: one
    body, as the hand-written loops were. The hooks are typed apart (``@helper_kernel``) and
    LLVM inlines them before it optimises; a call left here would cost ~2× in P2G. (Hooks this
    small, with one call site, LLVM would inline even without ``forceinline``: the flag is for the
    larger helpers the kernels call from several places, such as a corner's.)"""
    walk = _walk_2d if d == 2 else _walk_3d
    seen, count = np.zeros(1, np.int64), np.zeros(1, np.int64)
    walk(_boxes([0, 1], d), None, np.zeros((1, 1, 1)), np.full(2, -1, np.int64),
         Walked(np.ones(1), seen, count, None))
    assert count[0] == 1
    llvm = "".join(walk.inspect_llvm().values()).splitlines()
    names = ("_support", "_scatter", "each_particle")
    assert any(n in line for line in llvm for n in names)  # the names are as spelled here
    calls = [line for line in llvm if line.lstrip().startswith(("call", "%")) and " call " in
             f" {line.strip()} " and any(n in line for n in names)]
    assert calls == []


@pytest.mark.parametrize("kernels", [*KERNELS_2D.values(), MLS_KERNELS_2D,
                                     *KERNELS_3D.values(), MLS_KERNELS_3D])
def test_every_kernel_is_a_module_level_function_cached_to_the_sources(kernels):
    for k in kernels:
        assert k.py_func.__closure__ is None, k
        assert is_keyed(k) is True, k


@pytest.mark.parametrize("d", [1, 2, 3])
def test_cell_node_walks_a_cell_as_the_nested_loops_did(d):
    rng = np.random.default_rng(d)
    jk = rng.integers(0, 5, (3, 2))
    wk = rng.random((3, 2))
    L0, L1 = 7, 6
    want = []
    for i2 in range(2 if d > 2 else 1):
        w2 = wk[2, i2] if d > 2 else 1.0
        o2 = jk[2, i2] if d > 2 else 0
        for i1 in range(2 if d > 1 else 1):
            w1 = wk[1, i1] if d > 1 else 1.0
            o1 = jk[1, i1] if d > 1 else 0
            for i0 in range(2):
                want.append((jk[0, i0] + L0 * (o1 + L1 * o2), wk[0, i0] * w1 * w2))
    got = [cell_node(d, jk, wk, L0, L1, e) for e in range(1 << d)]
    assert got == want  # the same nodes in the same order, the same weights bit for bit
