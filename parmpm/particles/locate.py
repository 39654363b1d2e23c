"""Which patch each particle is in: the flat global patch id of its position (the id of
:mod:`parmpm.grid.patch_index`, the one G2P's specialised kernels compute as they move a
particle), for seeding, restarts, re-decomposition and the migration check."""
from __future__ import annotations

import numpy as np

from parmpm.core.jit import kernel, loop_kernel
from parmpm.core.records import AXES
from parmpm.grid.patch_index import patch_id1, patch_id2, patch_id3


def locate_patches(d, x, origin, inv_h, cells, psize, ppa, current, out, order=None):
    """Flat global patch id of each particle's position into ``out``; a particle outside the
    grid keeps ``current``. Returns (the row of the first particle outside the grid, in
    ``order`` (:meth:`parmpm.particles.store.Particles.order`), or -1; how many particles changed patch). The id is :mod:`parmpm.grid.patch_index`'s, the one G2P's
    specialised kernels use; the loop is compiled per dimension without reference counting."""
    if order is None:
        order = np.arange(x.shape[0], dtype=np.uint64)
    return _locate_patches(AXES[d], x, origin, inv_h, cells, psize, ppa, current, out, order)


@kernel
def _locate_patches(axes, x, origin, inv_h, cells, psize, ppa, current, out, order):
    d = len(axes)  # compiled per dimension (parmpm.core.records.AXES)
    loc = np.zeros((3, 3), np.int64)
    inv_ps = np.zeros(3)
    for k in range(d):
        loc[0, k], loc[1, k], loc[2, k] = cells[k], psize[k], ppa[k]
        inv_ps[k] = 1.0 / psize[k]
    return _locate_loop(axes, x, origin, inv_h, loc, inv_ps, current, out, order)


@loop_kernel
def _locate_loop(axes, x, origin, inv_h, loc, inv_ps, current, out, order):
    dim = len(axes)
    first = -1
    moved = 0
    for k in range(order.size):
        i = order[k]
        if dim == 1:
            pid = patch_id1(x[i, 0], origin, inv_h, loc, inv_ps)
        elif dim == 2:
            pid = patch_id2(x[i, 0], x[i, 1], origin, inv_h, loc, inv_ps)
        else:
            pid = patch_id3(x[i, 0], x[i, 1], x[i, 2], origin, inv_h, loc, inv_ps)
        if pid < 0:  # outside the grid (NaN too)
            out[i] = current[i]
            if first < 0:
                first = np.int64(i)
        else:
            out[i] = pid
            if pid != current[i]:
                moved += 1
    return first, moved
