"""The patch-box arithmetic of :mod:`decomposition.boxes`, compiled for the kernels.

``decomposition`` stays free of numba and of ``parmpm``; here its plain scalar functions become
``@helper_kernel`` helpers. The ones they call in turn are registered as numba overloads of the
plain functions, so numba compiles the very same source wherever it meets them. Kernels import
from here (not from the particle store)::

    from parmpm.grid.patch_index import patch_id2, patch_id3
"""
from numba.extending import overload

from decomposition import boxes
from parmpm.core.jit import HELPER_OVERLOAD_OPTIONS, helper_kernel


def _jitable(fn):
    """Let jitted code call the plain function ``fn`` (inlined by LLVM into the caller)."""
    overload(fn, jit_options=HELPER_OVERLOAD_OPTIONS, strict=False)(lambda *a: fn)
    return fn


for _fn in (boxes.patch_id, boxes.patch_of_cell, boxes.patch_of_coordinate):
    _jitable(_fn)

#: patch index along one axis of grid coordinate ``u``, or -1 outside the grid
patch_index = helper_kernel(boxes.patch_of_coordinate)
#: flat patch id of a 1D / 2D / 3D position, or -1 outside the grid
patch_id1 = helper_kernel(boxes.patch_of_point_1d)
patch_id2 = helper_kernel(boxes.patch_of_point_2d)
patch_id3 = helper_kernel(boxes.patch_of_point_3d)
#: (first, last) patch along one axis whose ghost-inclusive box holds a global node
patches_holding_node = helper_kernel(boxes.patches_holding_node)


@helper_kernel
def next_patch_2d(x0, x1, origin, inv_h, locate, p, sp):
    """:func:`patch_id2` of a particle of slot ``p`` (patch ``sp``) after its move. Almost every
    particle stays in its patch: a test of its grid coordinates against the patch's cells
    (``locate.inside[p]``) answers ``sp`` with no patch arithmetic (a fifth of 2D mpm's G2P time
    went to it). ``u`` is computed as :func:`decomposition.boxes.patch_of_point_2d` computes it
    and the cell bounds are integers, so ``lo ≤ u < hi`` holds exactly when ``⌊u⌋`` lies in the
    patch: the same answer (NaN fails the test and takes the full path)."""
    inside = locate.inside
    u0 = (x0 - origin[0]) * inv_h[0]
    u1 = (x1 - origin[1]) * inv_h[1]
    if (u0 >= inside[p, 0, 0] and u0 < inside[p, 1, 0]
            and u1 >= inside[p, 0, 1] and u1 < inside[p, 1, 1]):
        return sp
    return patch_id2(x0, x1, origin, inv_h, locate.loc, locate.inv_ps)


@helper_kernel
def next_patch_3d(x0, x1, x2, origin, inv_h, locate, p, sp):
    """:func:`next_patch_2d` in 3D."""
    inside = locate.inside
    u0 = (x0 - origin[0]) * inv_h[0]
    u1 = (x1 - origin[1]) * inv_h[1]
    u2 = (x2 - origin[2]) * inv_h[2]
    if (u0 >= inside[p, 0, 0] and u0 < inside[p, 1, 0]
            and u1 >= inside[p, 0, 1] and u1 < inside[p, 1, 1]
            and u2 >= inside[p, 0, 2] and u2 < inside[p, 1, 2]):
        return sp
    return patch_id3(x0, x1, x2, origin, inv_h, locate.loc, locate.inv_ps)
