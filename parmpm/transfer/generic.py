"""Particle ↔ grid transfers over any interpolator, patch by patch.

Every kernel walks patches in order and each patch's particles in their stored order
(sorted by global id within the patch), scattering into that patch's ghost-inclusive node box —
so each patch's partial sums are a deterministic function of its own particles.

* ``p2g``: ``m_i = Σ φ_ip m_p``, ``(mv)_i = Σ φ_ip m_p v_p``,
  ``f_i = −Σ V_p σ_p ∇φ_ip (+ Σ φ_ip m_p b_p)`` with ``V_p = J_p V0_p`` (the material volume, never
  the scaled CPDI domain's) and ``b_p`` a per-particle body force when one is given (an empty
  ``bforce`` means none; gravity is added on the grid);
* ``p2g_momentum``: the MUSL re-map of particle momentum;
* ``g2p``: FLIP/PIC velocity ``v_p ← α(v_p + Σ φ Δv_i) + (1−α) Σ φ v_i``, position
  ``x_p += Δt Σ φ v_i``, velocity gradient ``L_p = Σ v_i ⊗ ∇φ_ip``, ``F ← (I + Δt L) F`` and stress.

Under APIC (``how.apic``, :mod:`parmpm.transfer.affine`) the momentum scattered is the particle's affine
field at the node, ``m_p φ_ip (v_p + C_p (x_i − x_p))``, and G2P sets ``v_p = Σ φ v_i`` and
``C_p = Σ φ v_i ⊗ (x_i − x_p) D_p⁻¹`` with the B-spline's ``D_p⁻¹ = diag(4/Δx_k²)``.

Under MLS (``how.mls``, :mod:`parmpm.transfer.affine`) the transfers are APIC's and the weight gradient is
``∇̃φ_ip = φ_ip D_p⁻¹ (x_i − x_p)``: P2G adds ``Δt f_i`` (the step's, ``dt``) to the momentum and
still writes ``f_i`` (the grid update skips it, the energy ledger reads it), and G2P's velocity
gradient is ``L_p = C_p``.

Under cpdi2 (:mod:`parmpm.shapes.cpdi2`) G2P also moves the particle's tracked corners with the
grid, after the particle's motion: ``c_α ← c_α + Δt (v(x_p + ĉ_α) − v_move)``, ``v(y) = Σ_i S_i(y)
v_i`` the linear hat of the grid velocity, ``ĉ_α`` the corner as interpolated (after the ``l_cr``
cap) and ``v_move = Σ φ v_i``. Under MUSL the corners move in the deformation pass, with the
re-mapped grid velocity (the field that deforms F), and not in the motion pass: the re-map must
scatter momentum with the weights the mass was scattered with (the corners before the step), or a
node the old domain barely touched gets momentum without mass and a huge velocity. A
frozen particle's (``rf ≠ 0``, :mod:`parmpm.shapes.freeze`) corners no longer move relative to it
(docs/cpdi2.md).

A support that leaves the grid or the ghost layer sets ``err[0]`` (the first such particle) and
``err[1]`` its return code (-1 reach, -2 an inverted cpdi2 domain), and that particle is skipped:
the step still ends on every rank, and the caller stops the run.

Each public kernel allocates its scratch and hands it to a ``@loop_kernel`` body (``_*_loop``)
that runs the particle loop without reference counting (see :mod:`parmpm.core.jit`): one walk,
:func:`each_particle`, with each kernel's work per particle (``_*_one``) inlined into it. The
kernels are compiled once per dimension a run uses: ``how.axes`` (:data:`parmpm.core.records.AXES`)
has a type of its own per dimension, so ``d = len(how.axes)`` is a compile-time constant and LLVM
fully unrolls every ``range(d)`` loop, the helpers' included (1.2–1.4× over a runtime ``d``), and a
1D run never compiles the 2D and 3D loops.
"""
import math

import numpy as np

from parmpm.core.jit import helper_kernel, hook_helper_kernel, kernel, loop_kernel
from parmpm.grid.crack import field_node, to_fields
from parmpm.materials.damage import damage_update
from parmpm.materials.kinematics import det_d, flip_pic, update_F
from parmpm.materials.laws import cauchy_stress, wave_speed
from parmpm.shapes import CPDI, CPDI2
from parmpm.shapes.cpdi import cell_node
from parmpm.shapes.cpdi2 import SCRATCH_SHAPE
from parmpm.shapes.hat import hat_axis
from parmpm.shapes.support import domain_matrix, particle_support
from parmpm.transfer.affine_kernels import affine_gather, affine_scatter, mls_gradients, offsets
from parmpm.transfer.rows import row
from parmpm.transfer.update_order import G2P_MUSL_DEFORM, G2P_MUSL_MOTION, G2P_USL


@kernel
def loop_scratch(nloc, d):
    """Per-call scratch of the particle loops: ``R, C`` (CPDI domain and cofactor), ``xi`` (grid
    coordinates), the per-axis rows ``nk, jk, wk, dwk`` of :func:`particle_support`, its entries
    ``idx, w, g``, ``Lg, Fn`` (velocity gradient and new F in G2P) and ``r`` (each entry's node
    minus the particle, physical units: APIC), ``sc`` (cpdi2's capped corners and weights) and
    ``vm`` (the velocity that moved the particle: cpdi2's corner update)."""
    M = max(nloc[0], nloc[1], nloc[2], 4)
    K = 64
    prod = 1
    for k in range(d):
        prod *= nloc[k]
    K = max(K, prod)
    return (np.zeros((3, 3)), np.zeros((3, 3)), np.zeros(3), np.zeros(3, np.int64),
            np.zeros((3, M), np.int64), np.zeros((3, M)), np.zeros((3, M)),
            np.zeros(K, np.int64), np.zeros(K), np.zeros((K, 3)),
            np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((K, 3)), np.zeros(SCRATCH_SHAPE),
            np.zeros(3))


@helper_kernel
def _entries(kind, d, lcr, boxes, fields, i, p, err, scratch):
    """Particle ``i``'s (node, weight, gradient) entries in the scratch's ``idx, w, g`` for the
    node box of slot ``p``; their count, or -1 (noted in ``err``) when its support leaves the
    grid or the ghost layer, -2 (cpdi2: an inverted domain); a negative count is noted in
    ``err`` (particle, code) for the first such particle."""
    R, C, xi, nk, jk, wk, dwk, idx, w, g, _, _, _, sc, _ = scratch
    x, F = fields.x, fields.F
    origin, inv_h = boxes.origin, boxes.inv_h
    for k in range(d):
        xi[k] = (x[i, k] - origin[k]) * inv_h[k]
    if len(kind) == CPDI:  # a constant: the other interpolators compile no call
        domain_matrix(d, CPDI, lcr, F[i], fields.r0[i], R)
    n = particle_support(kind, d, xi, F[i], fields.lh0[i], R, C, boxes.base[p], boxes.nloc,
                         boxes.nglob, inv_h, nk, jk, wk, dwk, idx, w, g, fields.corners, i, lcr,
                         sc)
    if n < 0 and err[0] < 0:
        err[0] = i
        err[1] = n
    return n


@helper_kernel
def _move_corners(d, dt, gvel, p, base, nloc, nglob, inv_h, c, scratch, sides, i):
    """cpdi2: ``c_α += Δt (v(x_p + ĉ_α) − v_move)`` for the particle ``i`` whose capped corners
    ``ĉ`` :func:`_entries` left in the scratch (``sc``), ``v(y) = Σ_i S_i(y) v_i`` the linear hat
    of the grid velocity ``gvel`` of slot ``p`` (node box at ``base``; ``c`` the particle's
    corners, the scratch's ``vm`` its ``v_move``; with crack ``sides``, each node's copy in the
    particle's field there). The capped corners' nodes are in the box: the support held them."""
    xi, jk, wk, dwk, sc, vm = scratch[2], scratch[4], scratch[5], scratch[6], scratch[13], scratch[14]
    L0, L1 = nloc[0], nloc[1]
    for alpha in range(1 << d):
        for k in range(d):
            hat_axis(xi[k] + sc[alpha, k] * inv_h[k], base[k], nloc[k], nglob[k], inv_h[k],
                     jk, wk, dwk, k)
        for a in range(d):
            s = 0.0
            for e in range(1 << d):
                node, S = cell_node(d, jk, wk, L0, L1, e)
                s += S * gvel[p, field_node(sides, i, p, node), a]
            c[alpha, a] += dt * (s - vm[a])


@helper_kernel
def _frozen(d, rf):
    """A frozen domain (:mod:`parmpm.shapes.freeze`): ``rf`` not zero."""
    for a in range(d):
        if rf[a, 0] != 0.0:
            return True
    return False


@hook_helper_kernel
def each_particle(body, d, how, boxes, order, fields, err, scratch, out, args, acc, sides):
    """``acc = body(i, p, n, d, how, boxes, fields, scratch, out, args, acc)`` for every particle
    ``i`` of every patch slot ``p``, in canonical order, whose ``n`` support entries
    :func:`_entries` left in the scratch; one whose support fails is skipped (and noted in
    ``err``). With crack ``sides`` (:data:`parmpm.core.records.Sides`) each entry's node is
    moved to its field's copy in the stacked grid first (:func:`parmpm.grid.crack.to_fields`).
    Returns ``acc``. What a body writes comes as a kernel argument (``fields``,
    ``scratch``, ``out``), never in ``args``, a tuple built in the kernel
    (:mod:`parmpm.transfer.kernels2d.loops` says why)."""
    kind, lcr, start = how.kind, how.lcr, boxes.start
    for p in range(start.size - 1):
        for kk in range(np.uint64(start[p]), np.uint64(start[p + 1])):  # canonical order
            i = row(order, kk)
            n = _entries(kind, d, lcr, boxes, fields, i, p, err, scratch)
            if n >= 0:
                to_fields(sides, i, p, n, scratch[7])
                acc = body(i, p, n, d, how, boxes, fields, scratch, out, args, acc)
    return acc


@helper_kernel
def zero_node_major(a):
    """``a[:] = 0`` for a node-major view ``(slots, nodes, rows)`` of a ``(slots, rows, stride)``
    block, walked in memory order: numba's ``a[:] = 0.0`` steps through such a view node by node
    across the rows, 3-4x slower (a crack scene's stacked grid: 50-100 µs a pass, every pass)."""
    for p in range(a.shape[0]):
        for r in range(a.shape[2]):
            for j in range(a.shape[1]):
                a[p, j, r] = 0.0


@kernel
def p2g(how, boxes, fields, bforce, dt, out, err, sides):
    """``out = (gm, gmv, gf)`` (node-major views of this rank's patch slots) from the particles;
    ``how``, ``boxes``, ``fields``: :mod:`parmpm.core.records`; ``dt``: the step (MLS folds
    ``Δt f`` into the momentum; unused otherwise); ``sides``: crack faces (the stacked grid of
    every field, :data:`parmpm.core.records.Sides`) or None."""
    scratch = loop_scratch(boxes.nloc, len(how.axes))
    _p2g_loop(how, boxes, boxes.order, fields, bforce, dt, out, err, scratch, sides)


@loop_kernel
def _p2g_loop(how, boxes, order, fields, bforce, dt, out, err, scratch, sides):
    d = len(how.axes)  # a compile-time constant (the dimension is in how's type)
    gm, gmv, gf = out
    zero_node_major(gm)
    zero_node_major(gmv)
    zero_node_major(gf)
    each_particle(_p2g_one, d, how, boxes, order, fields, err, scratch, out, (bforce, dt), 0,
                  sides)


@helper_kernel
def _p2g_one(i, p, n, d, how, boxes, fields, scratch, out, args, acc):
    """P2G of particle ``i``'s entries into ``out = (gm, gmv, gf)`` (module doc)."""
    bforce, dt = args
    apic, mls = how.apic, how.mls
    v, F, mass, vol0, stress = fields.v, fields.F, fields.mass, fields.vol0, fields.stress
    gm, gmv, gf = out
    idx, w, g = scratch[7], scratch[8], scratch[9]
    forced = bforce.shape[0] > 0
    m = mass[i]
    V = det_d(d, F[i]) * vol0[i]
    if apic:
        offsets(d, boxes, p, n, scratch)
        affine_scatter(d, n, m, v[i], fields.affine[i], gmv, p, scratch)
        if mls:
            mls_gradients(d, n, boxes.inv_h, scratch)
    for e in range(n):
        node = idx[e]
        mw = m * w[e]
        gm[p, node, 0] += mw
        for a in range(d):
            if not apic:
                gmv[p, node, a] += mw * v[i, a]
            s = 0.0
            for b in range(d):
                s += stress[i, a, b] * g[e, b]
            gf[p, node, a] -= V * s
            if forced:
                gf[p, node, a] += mw * bforce[i, a]
            if mls:  # the grid update's Δt f, folded in (module doc)
                fa = mw * bforce[i, a] - V * s if forced else -V * s
                gmv[p, node, a] += dt * fa
    return acc


@kernel
def p2g_momentum(how, boxes, fields, gmv, err, sides):
    """The MUSL re-map of particle momentum into ``gmv`` (``sides``: as :func:`p2g`)."""
    scratch = loop_scratch(boxes.nloc, len(how.axes))
    _p2g_momentum_loop(how, boxes, boxes.order, fields, gmv, err, scratch, sides)


@loop_kernel
def _p2g_momentum_loop(how, boxes, order, fields, gmv, err, scratch, sides):
    d = len(how.axes)  # a compile-time constant (the dimension is in how's type)
    zero_node_major(gmv)
    each_particle(_p2g_momentum_one, d, how, boxes, order, fields, err, scratch, gmv, None, 0,
                  sides)


@helper_kernel
def _p2g_momentum_one(i, p, n, d, how, boxes, fields, scratch, gmv, args, acc):
    """The momentum of particle ``i``'s entries into ``gmv`` (APIC's affine field under APIC and
    MLS)."""
    v, mass = fields.v, fields.mass
    idx, w = scratch[7], scratch[8]
    if how.apic:
        offsets(d, boxes, p, n, scratch)
        affine_scatter(d, n, mass[i], v[i], fields.affine[i], gmv, p, scratch)
        return acc
    for e in range(n):
        mw = mass[i] * w[e]
        for a in range(d):
            gmv[p, idx[e], a] += mw * v[i, a]
    return acc


@kernel
def g2p(mode, how, boxes, dt, flip, fields, material, grid, err, sides):
    """One of the three G2P modes (:mod:`parmpm.transfer.update_order`) from ``grid = (v, Δv)`` node-major
    views. Returns the largest ``c_p + |v_p|`` over the particles (for the next CFL step) in the
    deformation modes."""
    scratch = loop_scratch(boxes.nloc, len(how.axes))
    return _g2p_loop(mode, how, boxes, boxes.order, dt, flip, fields, material, grid, err,
                     scratch, sides)


@loop_kernel
def _g2p_loop(mode, how, boxes, order, dt, flip, fields, material, grid, err, scratch, sides):
    d = len(how.axes)  # a compile-time constant (the dimension is in how's type)
    return each_particle(_g2p_one, d, how, boxes, order, fields, err, scratch, material,
                         (mode, dt, flip, grid, sides), 0.0, sides)


@helper_kernel
def _g2p_one(i, p, n, d, how, boxes, fields, scratch, material, args, vmax):
    """G2P of particle ``i`` from its entries and ``args = (mode, Δt, flip, (v, Δv))`` (module
    doc), updating ``fields`` and ``material``; returns the running largest ``c_p + |v_p|``."""
    mode, dt, flip, grid, sides = args
    apic, mls = how.apic, how.mls
    x, v, F, stress, dx = fields.x, fields.v, fields.F, fields.stress, fields.dx
    affine = fields.affine
    mat, params, damage = material.mat, material.params, material.damage
    gvel, gdv = grid
    idx, w, g, Lg, Fn, vm = scratch[7], scratch[8], scratch[9], scratch[10], scratch[11], scratch[14]
    corners, rf = fields.corners, fields.rf
    tracked = how.code == CPDI2
    Fi = F[i]
    if apic and mode != G2P_MUSL_DEFORM:
        offsets(d, boxes, p, n, scratch)
        affine_gather(d, n, gvel, p, boxes.inv_h, v[i], affine[i], scratch)
        for a in range(d):
            if mode == G2P_USL:
                x[i, a] += dt * v[i, a]
            else:
                dx[i, a] = dt * v[i, a]
    elif mode != G2P_MUSL_DEFORM:
        for a in range(d):
            vi = 0.0
            dvi = 0.0
            for e in range(n):
                vi += w[e] * gvel[p, idx[e], a]
                dvi += w[e] * gdv[p, idx[e], a]
            if mode == G2P_USL:
                x[i, a] += dt * vi
            else:
                dx[i, a] = dt * vi
            v[i, a] = flip_pic(flip, v[i, a], dvi, vi)
            vm[a] = vi
    if tracked and mode != G2P_MUSL_MOTION and not _frozen(d, rf[i]):
        if mode == G2P_MUSL_DEFORM:  # the re-mapped field moves the corners (see above)
            for a in range(d):
                vi = 0.0
                for e in range(n):
                    vi += w[e] * gvel[p, idx[e], a]
                vm[a] = vi
        _move_corners(d, dt, gvel, p, boxes.base[p], boxes.nloc, boxes.nglob,
                      boxes.inv_h, corners[i], scratch, sides, i)
    if mode == G2P_MUSL_MOTION:
        return vmax
    if mls and mode == G2P_USL:  # L = C, gathered above
        for a in range(d):
            for b in range(d):
                Lg[a, b] = affine[i, a, b]
    elif mls:  # the re-mapped field's C, not stored: the particle keeps the motion's
        offsets(d, boxes, p, n, scratch)
        affine_gather(d, n, gvel, p, boxes.inv_h, vm, Lg, scratch)
    else:
        for a in range(d):
            for b in range(d):
                s = 0.0
                for e in range(n):
                    s += gvel[p, idx[e], a] * g[e, b]
                Lg[a, b] = s
    update_F(d, dt, Lg, Fi, Fn)
    if mode == G2P_MUSL_DEFORM:
        for a in range(d):
            x[i, a] += dx[i, a]
    prm = params[mat[i]]
    damage[i] = damage_update(d, prm, Fi, damage[i])
    cauchy_stress(d, prm, Fi, damage[i], stress[i])
    speed2 = 0.0
    for a in range(d):
        speed2 += v[i, a] * v[i, a]
    s = wave_speed(d, prm, Fi) + math.sqrt(speed2)
    if not (s <= vmax):
        return s if s == s else math.inf  # a NaN stays visible as inf
    return vmax


@kernel
def support_nodes(how, boxes, fields, nodes, count, err):
    """Global flat ids of the nodes each particle touches with nonzero weight (for separation
    detection: particles sharing no node exchange no momentum). ``nodes`` is (N, K)."""
    _support_nodes_loop(how, boxes, boxes.order, fields, (nodes, count, err),
                        loop_scratch(boxes.nloc, len(how.axes)))


@loop_kernel
def _support_nodes_loop(how, boxes, order, fields, out, scratch):
    each_particle(_support_nodes_one, len(how.axes), how, boxes, order, fields, out[2], scratch, out,
                  None, 0, None)


@helper_kernel
def _support_nodes_one(i, p, n, d, how, boxes, fields, scratch, out, args, acc):
    """The global ids of particle ``i``'s nodes of nonzero weight into ``nodes[i]``, each once,
    their count into ``count[i]`` (``out = (nodes, count, err)``). A CPDI particle's corners
    often share a cell: its 4^d entries name 2^d-3^d nodes, and the count's table then looks up
    each node once (the comparisons here stay within the entries' few cache lines)."""
    nodes, count, err = out
    base, nloc, nglob = boxes.base, boxes.nloc, boxes.nglob
    idx, w = scratch[7], scratch[8]
    c = 0
    for e in range(n):
        if w[e] <= 0.0:
            continue
        seen = False
        for f in range(e):
            if idx[f] == idx[e] and w[f] > 0.0:
                seen = True
                break
        if seen:
            continue
        if c >= nodes.shape[1]:  # more than the ghost layer allows: the reach error
            if err[0] < 0:
                err[0] = i
                err[1] = -1
            break
        loc = idx[e]
        i0 = loc % nloc[0]
        i1 = (loc // nloc[0]) % nloc[1]
        i2 = loc // (nloc[0] * nloc[1])
        nodes[i, c] = (base[p, 0] + i0) + nglob[0] * ((base[p, 1] + i1) + nglob[1] * (base[p, 2] + i2))
        c += 1
    count[i] = c
    return acc
