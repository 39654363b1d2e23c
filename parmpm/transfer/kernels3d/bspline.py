"""3D quadratic B-spline transfers, FLIP or APIC: the 3×3×3 nodes around the nearest node.

The 3D counterpart of :mod:`parmpm.transfer.kernels2d.bspline` (same per-axis weights and rounding,
:func:`parmpm.transfer.kernels2d.bspline.spline_of` and :func:`parmpm.shapes.bspline.spline_weights`), on the
3D grid rows ``gsum[s, :, node] = (m, mv, f)`` and ``gnew[s, :, node] = (v, Δv)`` with
``node = i0 + L0 (i1 + L1 i2)``. APIC (``C_p`` in ``fields.affine``, :mod:`parmpm.transfer.affine`) is on
when the particles carry the affine field. MLS (:mod:`parmpm.transfer.kernels3d.mls`) shares this G2P with
``L_p = C_p`` in place of the gradient sums. The loops are :mod:`parmpm.transfer.kernels3d.loops`'.
"""
from parmpm.core.jit import helper_kernel, loop_kernel
from parmpm.shapes.bspline import spline_weights
from parmpm.transfer.kernels2d.bspline import spline_of
from parmpm.transfer.kernels2d.loops import stays
from parmpm.transfer.kernels3d.hat import add_force, body_force, volume_stress
from parmpm.transfer.kernels3d.loops import centre_support, each_particle, each_particle_g2p


@helper_kernel
def pick(k, a, b, c):
    """``(a, b, c)[k]`` for a loop index ``k`` in 0..2 (tuples cannot be indexed by it)."""
    return a if k == 0 else (b if k == 1 else c)


@helper_kernel
def support(i, frame, slot, lcr, fields):
    """Particle ``i``'s first node and offset per axis, ``(kx, ky, kz, tx, ty, tz)`` (``lcr``
    unused)."""
    return centre_support(spline_of, i, frame, slot, fields)


@helper_kernel
def scatter(i, g, frame, st, fields, args):
    """Mass, momentum (FLIP or APIC) and force of particle ``i`` into its 3×3×3 nodes."""
    v, mass, C = fields.v, fields.mass, fields.affine
    bforce, forced, apic, hx, hy, hz = args
    _, _, _, ihx, ihy, ihz, L0, L01 = frame
    kx, ky, kz, tx, ty, tz = st
    wx0, wx1, wx2, dx0, dx1, dx2 = spline_weights(tx, ihx)
    wy0, wy1, wy2, dy0, dy1, dy2 = spline_weights(ty, ihy)
    wz0, wz1, wz2, dz0, dz1, dz2 = spline_weights(tz, ihz)
    t = volume_stress(i, fields)
    m = mass[i]
    vx, vy, vz = v[i, 0], v[i, 1], v[i, 2]
    bf = body_force(bforce, forced, i, m)
    for c in range(3):
        wz, dz = pick(c, wz0, wz1, wz2), pick(c, dz0, dz1, dz2)
        rz = (c - 1 - tz) * hz
        for b in range(3):
            wy, dy = pick(b, wy0, wy1, wy2), pick(b, dy0, dy1, dy2)
            ry = (b - 1 - ty) * hy
            wyz, dyz, wdz = wy * wz, dy * wz, wy * dz
            row = kx + L0 * (ky + b) + L01 * (kz + c)
            for a in range(3):
                wx, dx = pick(a, wx0, wx1, wx2), pick(a, dx0, dx1, dx2)
                S = wx * wyz
                gx, gy, gz = dx * wyz, wx * dyz, wx * wdz
                mS = m * S
                ux, uy, uz = vx, vy, vz
                if apic:
                    rx = (a - 1 - tx) * hx
                    ux = vx + C[i, 0, 0] * rx + C[i, 0, 1] * ry + C[i, 0, 2] * rz
                    uy = vy + C[i, 1, 0] * rx + C[i, 1, 1] * ry + C[i, 1, 2] * rz
                    uz = vz + C[i, 2, 0] * rx + C[i, 2, 1] * ry + C[i, 2, 2] * rz
                node = row + a
                g[0, node] += mS
                g[1, node] += mS * ux
                g[2, node] += mS * uy
                g[3, node] += mS * uz
                add_force(g, node, S, gx, gy, gz, bf, t, forced)


@helper_kernel
def scatter_momentum(i, g, frame, st, fields, args):
    """Momentum (FLIP or APIC) of particle ``i`` into its 3×3×3 nodes."""
    v, mass, C = fields.v, fields.mass, fields.affine
    apic, hx, hy, hz = args
    _, _, _, ihx, ihy, ihz, L0, L01 = frame
    kx, ky, kz, tx, ty, tz = st
    wx0, wx1, wx2, _, _, _ = spline_weights(tx, ihx)
    wy0, wy1, wy2, _, _, _ = spline_weights(ty, ihy)
    wz0, wz1, wz2, _, _, _ = spline_weights(tz, ihz)
    m = mass[i]
    vx, vy, vz = v[i, 0], v[i, 1], v[i, 2]
    for c in range(3):
        wz = pick(c, wz0, wz1, wz2)
        rz = (c - 1 - tz) * hz
        for b in range(3):
            wyz = pick(b, wy0, wy1, wy2) * wz
            ry = (b - 1 - ty) * hy
            row = kx + L0 * (ky + b) + L01 * (kz + c)
            for a in range(3):
                mS = m * (pick(a, wx0, wx1, wx2) * wyz)
                ux, uy, uz = vx, vy, vz
                if apic:
                    rx = (a - 1 - tx) * hx
                    ux = vx + C[i, 0, 0] * rx + C[i, 0, 1] * ry + C[i, 0, 2] * rz
                    uy = vy + C[i, 1, 0] * rx + C[i, 1, 1] * ry + C[i, 1, 2] * rz
                    uz = vz + C[i, 2, 0] * rx + C[i, 2, 1] * ry + C[i, 2, 2] * rz
                g[1, row + a] += mS * ux
                g[2, row + a] += mS * uy
                g[3, row + a] += mS * uz


@helper_kernel
def spline_gather(step, i, g, frame, st, mls):
    """``v``, ``Δv`` (FLIP) or ``C`` (APIC) and ``Δt L`` at particle ``i`` from its 3×3×3 nodes;
    ``mls``: ``L_p = C_p`` (the affine matrix of the field G2P reads, ``Σ φ v_i ⊗ r D⁻¹``,
    :mod:`parmpm.transfer.affine`), not ``Σ v_i ⊗ ∇φ``."""
    dt, apic = step[1], step[3]
    _, _, _, ihx, ihy, ihz, L0, L01 = frame
    kx, ky, kz, tx, ty, tz = st
    wx0, wx1, wx2, dx0, dx1, dx2 = spline_weights(tx, ihx)
    wy0, wy1, wy2, dy0, dy1, dy2 = spline_weights(ty, ihy)
    wz0, wz1, wz2, dz0, dz1, dz2 = spline_weights(tz, ihz)
    # the sums factor by rows of three x-nodes: Σ_abc w_c w_b w_a u = Σ_bc w_c w_b (Σ_a w_a u)
    wr0, wr1, wr2 = wx0 * (-1.0 - tx), wx1 * (-tx), wx2 * (1.0 - tx)
    vx = vy = vz = dvx = dvy = dvz = 0.0
    l00 = l01 = l02 = l10 = l11 = l12 = l20 = l21 = l22 = 0.0
    # APIC: Σ φ v_i ⊗ (k − 1 − t) (grid units), row by row
    b00 = b01 = b02 = b10 = b11 = b12 = b20 = b21 = b22 = 0.0
    for c in range(3):
        wz, dz = pick(c, wz0, wz1, wz2), pick(c, dz0, dz1, dz2)
        rz = c - 1 - tz
        for b in range(3):
            wy, dy = pick(b, wy0, wy1, wy2), pick(b, dy0, dy1, dy2)
            ry = b - 1 - ty
            wyz, dyz, wdz = wy * wz, dy * wz, wy * dz
            n = kx + L0 * (ky + b) + L01 * (kz + c)
            u0, u1, u2 = g[0, n], g[0, n + 1], g[0, n + 2]
            s0, s1, s2 = g[1, n], g[1, n + 1], g[1, n + 2]
            q0, q1, q2 = g[2, n], g[2, n + 1], g[2, n + 2]
            sx = wx0 * u0 + wx1 * u1 + wx2 * u2
            sy = wx0 * s0 + wx1 * s1 + wx2 * s2
            sz = wx0 * q0 + wx1 * q1 + wx2 * q2
            vx += wyz * sx
            vy += wyz * sy
            vz += wyz * sz
            if not mls:
                l00 += wyz * (dx0 * u0 + dx1 * u1 + dx2 * u2)
                l10 += wyz * (dx0 * s0 + dx1 * s1 + dx2 * s2)
                l20 += wyz * (dx0 * q0 + dx1 * q1 + dx2 * q2)
                l01 += dyz * sx
                l11 += dyz * sy
                l21 += dyz * sz
                l02 += wdz * sx
                l12 += wdz * sy
                l22 += wdz * sz
            if apic:
                wry, wrz = wyz * ry, wyz * rz
                b00 += wyz * (wr0 * u0 + wr1 * u1 + wr2 * u2)
                b10 += wyz * (wr0 * s0 + wr1 * s1 + wr2 * s2)
                b20 += wyz * (wr0 * q0 + wr1 * q1 + wr2 * q2)
                b01 += wry * sx
                b11 += wry * sy
                b21 += wry * sz
                b02 += wrz * sx
                b12 += wrz * sy
                b22 += wrz * sz
            else:
                dvx += wyz * (wx0 * g[3, n] + wx1 * g[3, n + 1] + wx2 * g[3, n + 2])
                dvy += wyz * (wx0 * g[4, n] + wx1 * g[4, n + 1] + wx2 * g[4, n + 2])
                dvz += wyz * (wx0 * g[5, n] + wx1 * g[5, n + 1] + wx2 * g[5, n + 2])
    kx4, ky4, kz4 = 4.0 * ihx, 4.0 * ihy, 4.0 * ihz
    c00, c01, c02 = kx4 * b00, ky4 * b01, kz4 * b02
    c10, c11, c12 = kx4 * b10, ky4 * b11, kz4 * b12
    c20, c21, c22 = kx4 * b20, ky4 * b21, kz4 * b22
    if mls:
        l00, l01, l02, l10, l11, l12 = c00, c01, c02, c10, c11, c12
        l20, l21, l22 = c20, c21, c22
    return ((vx, vy, vz), (dvx, dvy, dvz), (c00, c01, c02, c10, c11, c12, c20, c21, c22),
            (dt * l00, dt * l01, dt * l02, dt * l10, dt * l11, dt * l12, dt * l20, dt * l21,
             dt * l22), ())


@helper_kernel
def gather(step, i, g, frame, st, shape, fields):
    """:func:`spline_gather` with ``L_p = Σ v_i ⊗ ∇φ``."""
    return spline_gather(step, i, g, frame, st, False)


@loop_kernel
def p2g_bspline(lcr, boxes, order, fields, bforce, gsum, err):
    """Mass, momentum (FLIP or APIC) and force of every patch slot from its particles (``lcr``
    unused: the signature is the CPDI kernel's)."""
    gsum[:] = 0.0
    ih = boxes.inv_h
    each_particle(support, scatter, boxes, order, gsum, err, lcr, fields,
                  (bforce, bforce.shape[0] > 0, fields.affine.shape[0] > 0, 1.0 / ih[0],
                   1.0 / ih[1], 1.0 / ih[2]))


@loop_kernel
def p2g_momentum_bspline(lcr, boxes, order, fields, gsum, err):
    """The MUSL re-map: momentum rows (1, 2, 3) of ``gsum`` only (FLIP or APIC)."""
    gsum[:, 1:4, :] = 0.0
    ih = boxes.inv_h
    each_particle(support, scatter_momentum, boxes, order, gsum, err, lcr, fields,
                  (fields.affine.shape[0] > 0, 1.0 / ih[0], 1.0 / ih[1], 1.0 / ih[2]))


@loop_kernel
def g2p_bspline(mode, lcr, boxes, order, dt, flip, fields, material, gnew, err, locate):
    """G2P in one of the three modes (FLIP/PIC blend or APIC); returns the largest
    ``c_p + |v_p|`` when the stress is updated, the particles that changed patch and the first
    that left the grid."""
    return each_particle_g2p(support, gather, stays,
                             (mode, dt, flip, fields.affine.shape[0] > 0), boxes, order, gnew,
                             err, locate, lcr, fields, material)

