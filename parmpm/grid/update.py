"""Grid phase on owned nodes: velocities from summed mass, momentum and force; boundary conditions.

``v_old = (mv)_i / m_i``, ``v_new = [v_old + Δt (f_i / m_i + g)] / (1 + c Δt)`` (gravity applied
as ``m_i g``; optional mass-proportional damping ``c``, taken implicitly — backward Euler in its
own term — so that any ``c`` is stable: explicit ``−c·v_old`` flips the velocity's sign once
``c Δt > 1`` and grows without bound past 2, which sent a body with ``c = 1e12`` off the grid),
then per-face conditions on the nodes of the
physical boundary faces and on every node of the exterior layer beyond them (``grid.exterior``:
cells kept outside the faces so that a particle domain next to a wall has nodes to reach; the
nodes there carry mass and momentum like any other) — fixed: ``v = 0``; slip: the normal
component is 0; symmetry and clamped: mirrors, even and odd (:mod:`parmpm.grid.symmetry` folds the
image into the P2G sums; here the face node's normal velocity, or all of it, is held at 0 and
gravity is reflected on the nodes beyond the face, which hold the image); free: nothing — then ``v = 0``
on every node inside a fixed region (a grip, e.g. the hanging bar's support) and ``v·n = 0`` inside
a slip region (a symmetry plane inside the grid; a mirror face is better for wide supports:
:mod:`parmpm.grid.symmetry`) — applied to both
``v_old`` and ``v_new`` so the FLIP increment ``Δv = v_new − v_old`` respects them too. Nodes with
mass below ``mass_eps`` get no force term (``f/m`` is unbounded as ``m → 0``) but keep
``v = (mv)/m``, a mean of their particles' velocities (all weights are ≥ 0): a GIMP domain that
overlaps a node by ``δ`` gives it ``φ ∝ δ²`` but ``∇φ ∝ δ``, so zeroing its velocity stressed a
rigidly translating body. Only empty nodes get ``v = 0``. Ghost nodes are left to ``fill``.

Under MLS (``fused``, :mod:`parmpm.transfer.affine`) P2G has already added ``Δt f_i`` to the momentum rows,
so ``v_old = (mv + Δt f)/m`` and ``v_new = [v_old + Δt g]/(1 + cΔt)``; the force rows are not
added (they are zero, or the energy ledger's copy of ``f``). Its force carries the weights of the
mass, so ``f/m`` stays bounded as ``m → 0`` and no node is exempt.
"""
import numpy as np

from parmpm.core.jit import helper_kernel, kernel, loop_kernel

#: row stride modulo 4 KiB (in doubles) of a grid block: 208 doubles = 1664 B puts the rows of a
#: 5-row block 768 B or more apart modulo 4 KiB, so stores to one row never falsely depend on loads
#: of another at the same 4 KiB offset (a measured 20 % slow-down of P2G with equal offsets)
ROW_STAGGER = 208

FREE, SLIP, FIXED, SYMMETRY, CLAMPED = 0, 1, 2, 3, 4
BC_CODES = {"free": FREE, "slip": SLIP, "fixed": FIXED, "symmetry": SYMMETRY, "clamped": CLAMPED}


@helper_kernel
def is_mirror(code):
    """A symmetry or clamped face: the nodes beyond it hold the mirror image
    (:mod:`parmpm.grid.symmetry`)."""
    return code == SYMMETRY or code == CLAMPED


@helper_kernel
def _beyond_face(k, side, gidx, face_lo, face_hi):
    """Node ``gidx`` lies strictly beyond face ``(k, side)`` (in the exterior layer)."""
    return gidx[k] < face_lo[k] if side == 0 else gidx[k] > face_hi[k]


@helper_kernel
def apply_bc(d, gidx, face_lo, face_hi, bc, vel):
    """Face conditions of a node at global index ``gidx``: the physical faces of axis ``k`` are
    the nodes ``face_lo[k]`` and ``face_hi[k]`` (0 and the last node without an exterior layer);
    a node beyond a face (in the exterior layer) is treated as the face demands, but for a
    mirror face, whose nodes beyond hold the image (:mod:`parmpm.grid.symmetry`)."""
    for k in range(d):
        side = -1
        if gidx[k] <= face_lo[k]:
            side = 0
        elif gidx[k] >= face_hi[k]:
            side = 1
        if side < 0 or bc[k, side] == FREE:
            continue
        if is_mirror(bc[k, side]) and _beyond_face(k, side, gidx, face_lo, face_hi):
            continue
        if bc[k, side] == FIXED or bc[k, side] == CLAMPED:
            for a in range(d):
                vel[a] = 0.0
        else:
            vel[k] = 0.0


@helper_kernel
def reflected_gravity(d, gidx, face_lo, face_hi, bc, gvec, out):
    """``out``: gravity at a node as the mirror image feels it — beyond a symmetry face its
    normal component reversed, beyond a clamped face all of it (the image of an odd reflection
    accelerates the opposite way) — so the pointwise grid update keeps the mirror."""
    for a in range(d):
        out[a] = gvec[a]
    for k in range(d):
        for side in range(2):
            if not (is_mirror(bc[k, side]) and _beyond_face(k, side, gidx, face_lo, face_hi)):
                continue
            if bc[k, side] == SYMMETRY:
                out[k] = -out[k]
            else:
                for a in range(d):
                    out[a] = -out[a]


@helper_kernel
def beyond_mirror(d, gidx, face_lo, face_hi, bc):
    """True for a node beyond a mirror (symmetry or clamped) face: it holds the image."""
    for k in range(d):
        for side in range(2):
            if is_mirror(bc[k, side]) and _beyond_face(k, side, gidx, face_lo, face_hi):
                return True
    return False


@helper_kernel
def apply_regions(d, gidx, origin, h, regions, normal, vel):
    """Constrain a node inside region boxes ``regions[r, 0] ≤ x ≤ regions[r, 1]``: all components
    (``normal[r] < 0``: a fixed region, e.g. a grip) or the ``normal[r]`` component only (a slip
    region: a symmetry plane inside the grid)."""
    for r in range(regions.shape[0]):
        inside = True
        for k in range(d):
            xk = origin[k] + gidx[k] * h[k]
            tol = 1e-9 * h[k]
            if xk < regions[r, 0, k] - tol or xk > regions[r, 1, k] + tol:
                inside = False
                break
        if not inside:
            continue
        if normal[r] < 0:
            for a in range(d):
                vel[a] = 0.0
        else:
            vel[normal[r]] = 0.0


def region_node_ranges(regions: np.ndarray, origin: np.ndarray, h: np.ndarray, d: int) -> np.ndarray:
    """Global node-index ranges ``[lo, hi]`` (per region and axis, one node wider on each side
    than the box) that hold every node :func:`apply_regions` could constrain: a cheap integer
    pre-filter, the exact test stays in :func:`apply_regions`."""
    out = np.zeros((regions.shape[0], 2, 3), np.int64)
    out[:, 0, :], out[:, 1, :] = -(2**40), 2**40
    for k in range(d):
        out[:, 0, k] = np.floor((regions[:, 0, k] - origin[k]) / h[k]).astype(np.int64) - 1
        out[:, 1, k] = np.ceil((regions[:, 1, k] - origin[k]) / h[k]).astype(np.int64) + 1
    return out


@helper_kernel
def near_region(gi0, gi1, gi2, ranges):
    for r in range(ranges.shape[0]):
        if (ranges[r, 0, 0] <= gi0 <= ranges[r, 1, 0] and ranges[r, 0, 1] <= gi1 <= ranges[r, 1, 1]
                and ranges[r, 0, 2] <= gi2 <= ranges[r, 1, 2]):
            return True
    return False


@kernel
def grid_update(axes, nodes, constraints, dt, gvec, damping, mass_eps, gsum, gnew, from_momentum_only,
                fused):
    """Owned-node update from the P2G block ``gsum[slot] = (m, mv, f)`` rows into the block
    ``gnew[slot] = (v, Δv)`` rows (:func:`grid_block` layout). With ``from_momentum_only`` (the
    MUSL re-map) only ``v = mv/m`` with boundary conditions is formed; ``fused``: MLS momentum
    rows that already hold ``Δt f`` (module doc). Constraints are applied
    only on nodes of a constrained face (at or beyond the global node indices ``face_lo``,
    ``face_hi`` of the physical faces) or near a region (``ranges``). ``axes``:
    :data:`parmpm.core.records.AXES` of the dimension, so the kernel and its node loop are compiled
    for the dimensions a run uses alone (as :mod:`parmpm.transfer.generic`'s loops); the loop runs
    without reference counting."""
    d = len(axes)
    bc = constraints.bc
    vold = np.zeros(3)
    vnew = np.zeros(3)
    gidx = np.zeros(3, np.int64)
    face = np.zeros((3, 2), np.bool_)  # constrained global faces
    mirror = False                     # any mirror face: gravity reflected beyond it
    for k in range(d):
        for side in range(2):
            face[k, side] = bc[k, side] != FREE
            mirror = mirror or is_mirror(bc[k, side])
    gref = np.zeros(3)
    _grid_loop(axes, nodes, constraints, dt, gvec, damping, mass_eps, gsum, gnew,
               from_momentum_only, fused, vold, vnew, gidx, face, mirror, gref)


@loop_kernel
def _grid_loop(axes, nodes, constraints, dt, gvec, damping, mass_eps, gsum, gnew,
               from_momentum_only, fused, vold, vnew, gidx, face, mirror, gref):
    d = len(axes)
    own_lo, own_hi, base, nloc, face_lo, face_hi = nodes
    bc, regions, normal, ranges, origin, h = constraints
    L0, L1 = nloc[0], nloc[1]
    nreg = ranges.shape[0]
    forced = not fused  # MLS: Δt f is in the momentum rows already
    # x / 1.0 is x, bit for bit: without damping that division (a third of the 2D update's
    # divisions) is skipped; in the step the 2D update went 2.4 -> 1.8-2.1 ns per particle
    damped = damping != 0.0
    for p in range(gsum.shape[0]):
        G = gsum[p]
        W = gnew[p]
        for i2 in range(own_lo[p, 2], own_hi[p, 2]):
            g2 = base[p, 2] + i2
            for i1 in range(own_lo[p, 1], own_hi[p, 1]):
                g1 = base[p, 1] + i1
                row_edge = ((face[1, 0] and g1 <= face_lo[1]) or (face[1, 1] and g1 >= face_hi[1])
                            or (face[2, 0] and g2 <= face_lo[2])
                            or (face[2, 1] and g2 >= face_hi[2]))
                row0 = L0 * (i1 + L1 * i2)
                for i0 in range(own_lo[p, 0], own_hi[p, 0]):
                    node = row0 + i0
                    g0 = base[p, 0] + i0
                    m = G[0, node]
                    if m > 0.0:
                        for a in range(d):
                            vold[a] = G[1 + a, node] / m
                        if not from_momentum_only:
                            for a in range(d):
                                fm = G[1 + d + a, node] / m if forced and m > mass_eps else 0.0
                                vnew[a] = vold[a] + dt * (fm + gvec[a])
                            if damped:
                                for a in range(d):
                                    vnew[a] = vnew[a] / (1.0 + damping * dt)
                    else:
                        for a in range(d):
                            vold[a] = 0.0
                            vnew[a] = 0.0
                    if (row_edge or (face[0, 0] and g0 <= face_lo[0])
                            or (face[0, 1] and g0 >= face_hi[0])
                            or (nreg > 0 and near_region(g0, g1, g2, ranges))):
                        gidx[0], gidx[1], gidx[2] = g0, g1, g2
                        if (mirror and m > 0.0 and not from_momentum_only
                                and beyond_mirror(d, gidx, face_lo, face_hi, bc)):
                            reflected_gravity(d, gidx, face_lo, face_hi, bc, gvec, gref)
                            for a in range(d):
                                fm = G[1 + d + a, node] / m if forced and m > mass_eps else 0.0
                                vnew[a] = vold[a] + dt * (fm + gref[a])
                                if damped:
                                    vnew[a] = vnew[a] / (1.0 + damping * dt)
                        apply_bc(d, gidx, face_lo, face_hi, bc, vold)
                        if nreg:
                            apply_regions(d, gidx, origin, h, regions, normal, vold)
                        if not from_momentum_only:
                            apply_bc(d, gidx, face_lo, face_hi, bc, vnew)
                            if nreg:
                                apply_regions(d, gidx, origin, h, regions, normal, vnew)
                    if from_momentum_only:
                        for a in range(d):
                            W[a, node] = vold[a]
                    else:
                        for a in range(d):
                            W[a, node] = vnew[a]
                            W[d + a, node] = vnew[a] - vold[a]


def row_stride(nodes: int) -> int:
    """The doubles between a grid block's rows of ``nodes`` nodes (:func:`grid_block`; the
    memory estimate, :mod:`parmpm.driver.footprint`, counts them)."""
    stride = (nodes + 511) // 512 * 512 + ROW_STAGGER
    return stride - 512 if stride - 512 >= nodes else stride


def grid_block(slots: int, rows: int, nodes: int) -> tuple[np.ndarray, np.ndarray]:
    """Zeroed storage for ``rows`` grid fields of every patch slot: ``(block, view)`` with
    ``block`` of shape ``(slots, rows, stride)`` (C order; component rows of a slot contiguous
    per node index, as the 2D kernels want) and ``view = block[:, :, :nodes]`` transposed to
    ``(slots, nodes, rows)``, the node-major shape the halo exchange and generic kernels index.
    ``stride ≥ nodes`` is padded so consecutive rows start ``ROW_STAGGER`` doubles apart modulo
    4 KiB."""
    stride = row_stride(nodes)
    block = np.zeros((slots, rows, stride))
    return block, block[:, :, :nodes].transpose(0, 2, 1)
