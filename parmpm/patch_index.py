"""The patch-box arithmetic of :mod:`decomposition.boxes`, compiled for the kernels.

``decomposition`` stays free of numba and of ``parmpm``; here its plain scalar functions become
``@inline_kernel`` helpers. The ones they call in turn are registered as numba overloads of the
plain functions, so numba compiles the very same source wherever it meets them. Kernels import
from here (not from the particle store)::

    from parmpm.patch_index import patch_id2, patch_id3
"""
from numba.extending import overload

from decomposition import boxes
from parmpm.jit import JIT_OPTIONS, inline_kernel

_OVERLOAD_OPTIONS = {k: v for k, v in JIT_OPTIONS.items() if k != "cache"}


def _jitable(fn):
    """Let jitted code call the plain function ``fn`` (inlined into the caller's IR)."""
    overload(fn, jit_options=_OVERLOAD_OPTIONS, inline="always", strict=False)(lambda *a: fn)
    return fn


for _fn in (boxes.patch_id, boxes.patch_of_cell, boxes.patch_of_coordinate):
    _jitable(_fn)

#: patch index along one axis of grid coordinate ``u``, or -1 outside the grid
patch_index = inline_kernel(boxes.patch_of_coordinate)
#: flat patch id of a 1D / 2D / 3D position, or -1 outside the grid
patch_id1 = inline_kernel(boxes.patch_of_point_1d)
patch_id2 = inline_kernel(boxes.patch_of_point_2d)
patch_id3 = inline_kernel(boxes.patch_of_point_3d)
#: (first, last) patch along one axis whose ghost-inclusive box holds a global node
patches_holding_node = inline_kernel(boxes.patches_holding_node)
