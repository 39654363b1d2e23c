"""2D quadratic B-spline transfers, FLIP or APIC: the 3×3 nodes around the particle's nearest node.

Per axis, with the nearest node ``c`` and ``t = ξ − c ∈ [−1/2, 1/2)`` (:mod:`parmpm.shapes.bspline`
has the weights and the rounding rule, :func:`~parmpm.shapes.bspline.nearest_node` and
:func:`~parmpm.shapes.bspline.spline_weights`, which this module calls), the nodes
``c − 1, c, c + 1`` get ``N = (½(½ − t)², ¾ − t², ½(½ + t)²)`` and ``N' = (t − ½, −2t, t + ½)/Δx``.
P2G scatters ``φ m_p``, the momentum ``φ m_p v_p`` (APIC: ``φ m_p (v_p + C_p r)`` with
``r = x_i − x_p = (k − 1 − t)Δx`` per axis) and ``−V_p σ_p ∇φ (+ φ m_p b_p)``; G2P gathers
``v_p`` (FLIP/PIC blend, or APIC's ``Σ φ v_i`` and ``C_p = Σ φ v_i ⊗ r · 4/Δx²``) and
``L_p = Σ v_i ⊗ ∇φ`` (:mod:`parmpm.transfer.generic` and :mod:`parmpm.transfer.affine` have the equations).

APIC is on when the particles carry the affine field (``fields.affine`` has rows): the kernels
need no extra argument and FLIP runs pay one branch per particle. MLS (:mod:`parmpm.transfer.kernels2d.mls`)
shares this G2P with ``L_p = C_p`` in place of the gradient sums. The loops are
:mod:`parmpm.transfer.kernels2d.loops`'.
"""
from parmpm.core.jit import helper_kernel, loop_kernel
from parmpm.shapes.bspline import nearest_node, spline_weights
from parmpm.transfer.kernels2d.hat import add_force, body_force, volume_stress
from parmpm.transfer.kernels2d.loops import centre_support, each_particle, each_particle_g2p, stays
from parmpm.transfer.sided import sided_node


@helper_kernel
def spline_of(xi, base, jlo, jhi):
    """(local index of node ``c − 1``, ``t``) along one axis, or ``(-1, 0)`` when the three nodes
    leave the grid or the patch's box (usable cells ``jlo..jhi`` as for the hat: nodes
    ``jlo..jhi + 1``)."""
    c, t = nearest_node(xi)
    lo = c - 1
    if lo < jlo or lo + 2 > jhi + 1:
        return -1, 0.0
    return lo - base, t


@helper_kernel
def support(i, frame, slot, lcr, fields):
    """Particle ``i``'s first node and offset per axis, ``(kx, ky, tx, ty)`` (``lcr`` unused)."""
    return centre_support(spline_of, i, frame, slot, fields)


@helper_kernel
def scatter(i, g, frame, st, fields, args, side):
    """Mass, momentum (FLIP or APIC) and force of particle ``i`` into its 3×3 nodes."""
    v, mass, C = fields.v, fields.mass, fields.affine
    bforce, forced, apic, hx, hy = args
    _, _, ihx, ihy, L0 = frame
    kx, ky, tx, ty = st
    wx0, wx1, wx2, dx0, dx1, dx2 = spline_weights(tx, ihx)
    wy0, wy1, wy2, dy0, dy1, dy2 = spline_weights(ty, ihy)
    t = volume_stress(i, fields)
    m = mass[i]
    vx, vy = v[i, 0], v[i, 1]
    c00 = c01 = c10 = c11 = 0.0
    if apic:
        c00, c01, c10, c11 = C[i, 0, 0], C[i, 0, 1], C[i, 1, 0], C[i, 1, 1]
    bfx, bfy = body_force(bforce, forced, i, m)
    for b in range(3):
        wy = wy0 if b == 0 else (wy1 if b == 1 else wy2)
        dy = dy0 if b == 0 else (dy1 if b == 1 else dy2)
        ry = (b - 1 - ty) * hy
        row = kx + L0 * (ky + b)
        for a in range(3):
            wx = wx0 if a == 0 else (wx1 if a == 1 else wx2)
            dx = dx0 if a == 0 else (dx1 if a == 1 else dx2)
            S = wx * wy
            gx, gy = dx * wy, wx * dy
            mS = m * S
            ux, uy = vx, vy
            if apic:
                rx = (a - 1 - tx) * hx
                ux = vx + c00 * rx + c01 * ry
                uy = vy + c10 * rx + c11 * ry
            node = sided_node(side, i, row + a)
            g[0, node] += mS
            g[1, node] += mS * ux
            g[2, node] += mS * uy
            add_force(g, node, S, gx, gy, bfx, bfy, t, forced)


@helper_kernel
def scatter_momentum(i, g, frame, st, fields, args, side):
    """Momentum (FLIP or APIC) of particle ``i`` into its 3×3 nodes."""
    v, mass, C = fields.v, fields.mass, fields.affine
    apic, hx, hy = args
    _, _, ihx, ihy, L0 = frame
    kx, ky, tx, ty = st
    wx0, wx1, wx2, _, _, _ = spline_weights(tx, ihx)
    wy0, wy1, wy2, _, _, _ = spline_weights(ty, ihy)
    m = mass[i]
    vx, vy = v[i, 0], v[i, 1]
    c00 = c01 = c10 = c11 = 0.0
    if apic:
        c00, c01, c10, c11 = C[i, 0, 0], C[i, 0, 1], C[i, 1, 0], C[i, 1, 1]
    for b in range(3):
        wy = wy0 if b == 0 else (wy1 if b == 1 else wy2)
        ry = (b - 1 - ty) * hy
        row = kx + L0 * (ky + b)
        for a in range(3):
            wx = wx0 if a == 0 else (wx1 if a == 1 else wx2)
            mS = m * (wx * wy)
            ux, uy = vx, vy
            if apic:
                rx = (a - 1 - tx) * hx
                ux = vx + c00 * rx + c01 * ry
                uy = vy + c10 * rx + c11 * ry
            node = sided_node(side, i, row + a)
            g[1, node] += mS * ux
            g[2, node] += mS * uy


@helper_kernel
def spline_gather(step, i, g, frame, st, mls, side):
    """``v``, ``Δv`` (FLIP) or ``C`` (APIC) and ``Δt L`` at particle ``i`` from its 3×3 nodes;
    ``mls``: ``L_p = C_p`` (the affine matrix of the field G2P reads, ``Σ φ v_i ⊗ r D⁻¹``,
    :mod:`parmpm.transfer.affine`), not ``Σ v_i ⊗ ∇φ``."""
    dt, apic = step[1], step[3]
    _, _, ihx, ihy, L0 = frame
    kx, ky, tx, ty = st
    wx0, wx1, wx2, dx0, dx1, dx2 = spline_weights(tx, ihx)
    wy0, wy1, wy2, dy0, dy1, dy2 = spline_weights(ty, ihy)
    # the 3×3 sums factor by rows: Σ_ab wy_b wx_a u = Σ_b wy_b (Σ_a wx_a u_ab)
    wr0, wr1, wr2 = wx0 * (-1.0 - tx), wx1 * (-tx), wx2 * (1.0 - tx)
    vx = vy = dvx = dvy = 0.0
    l00 = l01 = l10 = l11 = 0.0
    bx0 = bx1 = by0 = by1 = 0.0
    for b in range(3):
        wy = wy0 if b == 0 else (wy1 if b == 1 else wy2)
        dy = dy0 if b == 0 else (dy1 if b == 1 else dy2)
        n = kx + L0 * (ky + b)
        n0, n1, n2 = sided_node(side, i, n), sided_node(side, i, n + 1), sided_node(side, i, n + 2)
        u0, u1, u2 = g[0, n0], g[0, n1], g[0, n2]
        w0, w1, w2 = g[1, n0], g[1, n1], g[1, n2]
        sx = wx0 * u0 + wx1 * u1 + wx2 * u2
        sy = wx0 * w0 + wx1 * w1 + wx2 * w2
        vx += wy * sx
        vy += wy * sy
        if not mls:
            l00 += wy * (dx0 * u0 + dx1 * u1 + dx2 * u2)
            l10 += wy * (dx0 * w0 + dx1 * w1 + dx2 * w2)
            l01 += dy * sx
            l11 += dy * sy
        if apic:
            ry = wy * (b - 1 - ty)
            bx0 += wy * (wr0 * u0 + wr1 * u1 + wr2 * u2)
            by0 += wy * (wr0 * w0 + wr1 * w1 + wr2 * w2)
            bx1 += ry * sx
            by1 += ry * sy
        else:
            dvx += wy * (wx0 * g[2, n0] + wx1 * g[2, n1] + wx2 * g[2, n2])
            dvy += wy * (wx0 * g[3, n0] + wx1 * g[3, n1] + wx2 * g[3, n2])
    c00, c01 = 4.0 * ihx * bx0, 4.0 * ihy * bx1
    c10, c11 = 4.0 * ihx * by0, 4.0 * ihy * by1
    if mls:
        l00, l01, l10, l11 = c00, c01, c10, c11
    return ((vx, vy), (dvx, dvy), (c00, c01, c10, c11),
            (dt * l00, dt * l01, dt * l10, dt * l11), ())


@helper_kernel
def gather(step, i, g, frame, st, shape, fields, side):
    """:func:`spline_gather` with ``L_p = Σ v_i ⊗ ∇φ``."""
    return spline_gather(step, i, g, frame, st, False, side)


@loop_kernel
def p2g_bspline(lcr, boxes, order, fields, bforce, gsum, err):
    """Mass, momentum (FLIP or APIC) and force of every patch slot from its particles (``lcr``
    unused: the signature is the CPDI kernel's)."""
    gsum[:] = 0.0
    ihx, ihy = boxes.inv_h[0], boxes.inv_h[1]
    each_particle(support, scatter, boxes, order, gsum, err, lcr, fields,
                  (bforce, bforce.shape[0] > 0, fields.affine.shape[0] > 0, 1.0 / ihx, 1.0 / ihy))


@loop_kernel
def p2g_momentum_bspline(lcr, boxes, order, fields, gsum, err):
    """The MUSL re-map: momentum only (FLIP or APIC), into ``gsum[..., 1:3]``."""
    gsum[:, 1:3, :] = 0.0
    ihx, ihy = boxes.inv_h[0], boxes.inv_h[1]
    each_particle(support, scatter_momentum, boxes, order, gsum, err, lcr, fields,
                  (fields.affine.shape[0] > 0, 1.0 / ihx, 1.0 / ihy))


@loop_kernel
def g2p_bspline(mode, lcr, boxes, order, dt, flip, fields, material, gnew, err, locate):
    """G2P in one of the three modes (FLIP/PIC blend or APIC); returns the largest
    ``c_p + |v_p|`` when the stress is updated, the particles that changed patch and the first
    that left the grid."""
    return each_particle_g2p(support, gather, stays,
                             (mode, dt, flip, fields.affine.shape[0] > 0), boxes, order, gnew,
                             err, locate, lcr, fields, material)

