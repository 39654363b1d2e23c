"""The records the transfer and grid kernels take, instead of twenty-odd positional arrays.

numba compiles a namedtuple of arrays like the arrays themselves (each field keeps its type), so
grouping costs nothing at run time and the kernels unpack the fields they use by name. The
stepper builds them (:meth:`parmpm.step.stepper.Stepper.records`); the tests call kernels through the
stepper.
"""
from __future__ import annotations

import math
from collections import namedtuple

#: ``l_cr`` as the kernels see it when there is no domain scaling: a cap no vector reaches
NO_SCALING = math.inf


def kernel_lcr(lcr: float | None) -> float:
    """The kernels' ``l_cr`` for a run's (``None``: no domain scaling). ``None`` is the one
    spelling of "no l_cr" above the kernels; inside them it is :data:`NO_SCALING`, which the cap
    formula needs no special case for."""
    if lcr is None:
        return NO_SCALING
    lcr = float(lcr)
    if not lcr > 0.0:
        raise ValueError(f"l_cr must be positive or None, got {lcr!r}")
    return lcr

#: the axes of a ``d``-dimensional problem, ``(0, …, d−1)``, by ``d``. A kernel argument holding
#: them has a numba type of its own per dimension, so the kernel is compiled (and cached) for the
#: dimensions a run uses and no other, with ``d = len(axes)`` a compile-time constant (LLVM unrolls
#: every ``range(d)``)
AXES = {1: (0,), 2: (0, 1), 3: (0, 1, 2)}

#: the interpolator code, the axes (:data:`AXES`), ``l_cr`` (:data:`NO_SCALING`: no domain scaling),
#: whether transfers are affine (APIC or MLS, :mod:`parmpm.transfer.affine`) rather than FLIP/PIC, and
#: whether the weight gradient is MLS's (force and ``L`` from ``φ D⁻¹ r``, ``Δt f`` folded into
#: the momentum), and the code again as the support's switch takes it (:data:`parmpm.shapes.KINDS`)
Method = namedtuple("Method", ("code", "axes", "lcr", "apic", "mls", "kind"))
#: a rank's patches in slot order: particle ranges ``start`` of the canonical ``order`` (slot
#: ``s`` holds physical rows ``order[start[s]:start[s + 1]]``; None: rows ``start[s]`` on, see
#: :meth:`parmpm.particles.store.Particles.lazy_order`; the loops take it as an argument of its own so
#: that numba prunes the branch on None; the stepper hands the generic loops an index always),
#: node-box origins ``base``, usable cells ``jlo..jhi``, box and grid node counts, grid origin
#: and ``1/Δx`` (3-axis padded)
Boxes = namedtuple("Boxes", ("start", "order", "base", "jlo", "jhi", "nloc", "nglob", "origin",
                             "inv_h"))
#: the particle fields a transfer reads or writes (``affine``, ``corners``: optional fields, empty
#: unless carried; ``rf``: which domains are frozen; ``sides``: crack faces for the specialised
#: 2D kernels that choose each node's copy themselves (:mod:`parmpm.transfer.sided`), else None)
Fields = namedtuple("Fields", ("x", "v", "F", "r0", "lh0", "mass", "vol0", "stress", "dx",
                               "affine", "corners", "rf", "sides"))
#: crack faces (``[contact] cracks``, :mod:`parmpm.grid.crack`): the side of a crack each
#: (particle, node) pair is on. ``field``: each physical row's body field; ``fields``: how many
#: body fields (a row on the far side of a node's crack goes to ``field + fields``); ``grad``:
#: each row's damage gradient (n, 3); ``normal``: each node's crack normal (slots, 3, stride;
#: zero where the node has no crack); ``stride``: how far apart two fields' copies of a node are
#: in the stacked grid the transfers fill; ``near``: per slot, whether its node box holds a node
#: with a crack normal (every slot where that is not known)
Sides = namedtuple("Sides", ("field", "fields", "grad", "normal", "stride", "near"))
#: the material state G2P updates: material row per particle, parameter table, damage; ``cfl``:
#: True where the step is the CFL one (the specialised G2P returns the largest ``c + |v|``), None
#: with a fixed step (it returns only whether all stayed finite: :mod:`parmpm.transfer.
#: running_speed`; the generic loops always give the speed)
Material = namedtuple("Material", ("mat", "params", "damage", "cfl"))
#: what the specialised G2P kernels need to find each particle's next patch (and write it);
#: ``inside[s]``: rows lo, hi of slot ``s``'s patch cells in grid coordinates (float, 3-axis
#: padded), so a particle that stays needs no patch arithmetic
Locate = namedtuple("Locate", ("loc", "inv_ps", "slot_patch", "new_patch", "inside"))
#: the nodes a rank's grid update visits: per-slot owned node ranges ``own_lo..own_hi`` in the
#: node box at ``base`` of ``nloc`` nodes, and the global nodes of the physical faces
OwnedNodes = namedtuple("OwnedNodes", ("own_lo", "own_hi", "base", "nloc", "face_lo", "face_hi"))
#: the velocity constraints: face conditions per axis and side, region boxes with their normals
#: (−1: fixed) and node ranges, and the grid geometry that places nodes in the boxes
Constraints = namedtuple("Constraints", ("bc", "regions", "normal", "ranges", "origin", "h"))
