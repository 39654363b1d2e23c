"""The physical row of a particle at canonical position ``kk``: the particle loops' one index rule.

A rank's particles are walked in canonical order (:class:`parmpm.core.records.Boxes`): position
``kk`` of ``order`` is physical row ``order[kk]``, or row ``kk`` itself when ``order`` is None (rows
already in canonical order, :meth:`parmpm.particles.store.Particles.lazy_order`). numba compiles
:func:`row` for the type of ``order``, so the None case has no branch and no load, as a test on
the argument inside one kernel had; as an overload it stays so inside the inlined loops of
:mod:`parmpm.transfer.kernels2d.loops` and :mod:`parmpm.transfer.kernels3d.loops`, where numba's
pruning of ``order is None`` no longer sees an argument.

LLVM inlines it (``forceinline``), not numba: an overload numba inlines makes numba run its
dead-code elimination on the kernel, which does not follow an array through a tuple built in the
kernel and drops writes into it (a loop's ``args``).
"""
from numba import types
from numba.extending import overload

from parmpm.core.jit import HELPER_OVERLOAD_OPTIONS


def row(order, kk):
    """``kk`` when ``order`` is None, else ``order[kk]``."""
    return kk if order is None else order[kk]


@overload(row, jit_options=HELPER_OVERLOAD_OPTIONS)
def _row(order, kk):
    if isinstance(order, types.NoneType):
        return lambda order, kk: kk
    return lambda order, kk: order[kk]
