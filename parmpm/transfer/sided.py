"""Crack faces inside the specialised loops: each (particle, node) pair's copy of the node in the
stacked grid, chosen where the interpolator touches the node (:mod:`parmpm.grid.crack` has the
method; the generic loops do the same through :func:`parmpm.grid.crack.field_node`).

A loop asks :func:`slot_side` once per patch slot and passes what it gives to its hooks, which
map every node they touch with :func:`sided_node`. Without crack faces (``sides`` None, the type
every other run compiles for) both are the identity and compile to nothing: the kernels' code is
what it was. With them, a slot whose node box holds no node with a crack normal (``sides.near``
False) keeps every node in the particle's own field, field 0's copy in a scene of one body, with
one predictable branch a node; a slot near a crack takes ``field_node``'s copy.

Overloads inlined by LLVM, as :func:`parmpm.transfer.rows.row` and for the same reason.
"""
from numba import types
from numba.extending import overload

from parmpm.grid.crack import field_node
from parmpm.core.jit import HELPER_OVERLOAD_OPTIONS


def slot_side(sides, p):
    """What :func:`sided_node` needs of slot ``p``: None without crack faces, else
    ``(sides, p, sides.near[p])``."""
    return None if sides is None else (sides, p, sides.near[p])


def sided_node(side, i, node):
    """Row ``i``'s copy of ``node`` of the slot :func:`slot_side` described: ``node`` itself
    away from a crack, else ``node + field · stride`` for its field at that node."""
    if side is None or not side[2]:
        return node
    return field_node(side[0], i, side[1], node)


@overload(slot_side, jit_options=HELPER_OVERLOAD_OPTIONS)
def _slot_side(sides, p):
    if isinstance(sides, types.NoneType):
        return lambda sides, p: None
    return lambda sides, p: (sides, p, sides.near[p])


@overload(sided_node, jit_options=HELPER_OVERLOAD_OPTIONS)
def _sided_node(side, i, node):
    if isinstance(side, types.NoneType):
        return lambda side, i, node: node

    def impl(side, i, node):
        if not side[2]:
            return node
        return field_node(side[0], i, side[1], node)
    return impl
