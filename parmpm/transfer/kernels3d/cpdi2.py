"""3D CPDI2 transfers over a particle's eight tracked hexahedron corners.

The corners (relative to the particle, bit order of :mod:`parmpm.shapes.cpdi2`) are capped at
``l_cr`` one by one, and the hexahedron's weights ``wf_α`` and ``wg_α`` are those of
:func:`parmpm.shapes.cpdi2.domain_weights` (2×2×2 Gauss points, exact for the trilinear map), with
``J`` assembled from the map's coefficients (:func:`hex_weights`).
Then, as :mod:`parmpm.transfer.kernels3d.cpdi` does for CPDI1's corners: P2G scatters, per corner,
``wf_α m_p`` (mass), ``wf_α m_p v_p`` (momentum) and ``−V_p σ_p wg_α (+ wf_α m_p b_p)`` (force)
into the eight nodes of the corner's cell; G2P gathers ``v(x_α)``, ``Δv(x_α)`` there and forms
``v_p = Σ wf_α v(x_α)`` (FLIP blend with ``Δv``), ``L_p = Σ v(x_α) ⊗ wg_α``, and moves the
corners, ``c_α += Δt (v(x_α) − Σ wf v(x_α))``, in USL and in MUSL's deformation pass (not a
frozen particle's; :mod:`parmpm.transfer.generic` says why). Errors as in :mod:`parmpm.transfer.kernels2d.cpdi2`.

The per-particle scratch (capped corners and weights, the corners' cells and fractions, their
velocities) comes from the ``@kernel`` wrappers; the loops (:mod:`parmpm.transfer.kernels3d.loops`)
run without reference counting.
"""
import numpy as np

from parmpm.core.jit import helper_kernel, kernel, loop_kernel
from parmpm.shapes.cpdi2 import (GAUSS, SCRATCH_SHAPE, WF, WG, add_point_weights, cap_corners,
                                  corner_shape, normalise_weights)
from parmpm.transfer.kernels2d.cells import cell_of
from parmpm.transfer.kernels3d.cpdi import gather6, scatter7, scatter_mv
from parmpm.transfer.kernels3d.hat import body_force, volume_stress
from parmpm.transfer.kernels3d.loops import ZERO9, each_particle, each_particle_g2p


@kernel
def _scratch(lcr):
    """The loops' ``shape``: ``lcr`` and the scratch (capped corners and weights ``sc``, the
    corners' ``cells`` and fractions ``fr``, their velocities ``u``: G2P). It allocates, so it is
    a ``@kernel`` (called once per transfer), not a helper."""
    return (lcr, np.zeros(SCRATCH_SHAPE), np.zeros((8, 3), np.int64), np.zeros((8, 3)),
            np.zeros((8, 6)))


def _shape_table() -> np.ndarray:
    """``N_α`` and ``∂N_α/∂ξ_m`` at the eight Gauss points (q, α, (N, dN0, dN1, dN2)): constants
    numba folds into the kernels, where :func:`parmpm.shapes.cpdi2.corner_shape` would recompute
    them per particle."""
    out = np.zeros((8, 8, 4))
    for q in range(8):
        e = [GAUSS if (q >> m) & 1 else -GAUSS for m in range(3)]
        for al in range(8):
            out[q, al] = corner_shape.py_func(al, 3, e[0], e[1], e[2])
    return out


SHAPES = _shape_table()


@helper_kernel
def coefficients(sc, k):
    """Component ``k`` of the trilinear map ``x(ξ) = A0 + A1 ξ + A2 η + A3 ζ + A12 ξη + A23 ηζ
    + A13 ξζ + A123 ξηζ`` of the corners in ``sc`` (bit order): ``(A1, A2, A3, A12, A23, A13,
    A123)``; ``A0`` does not enter the weights."""
    c0, c1, c2, c3 = sc[0, k], sc[1, k], sc[2, k], sc[3, k]
    c4, c5, c6, c7 = sc[4, k], sc[5, k], sc[6, k], sc[7, k]
    return (0.125 * ((c1 - c0) + (c3 - c2) + (c5 - c4) + (c7 - c6)),
            0.125 * ((c2 - c0) + (c3 - c1) + (c6 - c4) + (c7 - c5)),
            0.125 * ((c4 - c0) + (c5 - c1) + (c6 - c2) + (c7 - c3)),
            0.125 * ((c0 - c1) + (c3 - c2) + (c4 - c5) + (c7 - c6)),
            0.125 * ((c0 - c2) + (c1 - c3) + (c6 - c4) + (c7 - c5)),
            0.125 * ((c0 - c1) + (c2 - c3) + (c5 - c4) + (c7 - c6)),
            0.125 * ((c1 - c0) + (c2 - c3) + (c4 - c5) + (c7 - c6)))


@helper_kernel
def hex_weights(sc):
    """:func:`parmpm.shapes.cpdi2.domain_weights` for a hexahedron, with ``J`` from the map's
    coefficients (3 × 4 terms per Gauss point instead of a sum over the eight corners): fills
    ``sc[α, WF]``, ``sc[α, WG:WG+3]`` and returns ``V``."""
    x1, x2, x3, x12, x23, x13, x123 = coefficients(sc, 0)
    y1, y2, y3, y12, y23, y13, y123 = coefficients(sc, 1)
    z1, z2, z3, z12, z23, z13, z123 = coefficients(sc, 2)
    for a in range(8):
        for k in range(WF, WG + 3):
            sc[a, k] = 0.0
    vol = 0.0
    for q in range(8):
        e0 = GAUSS if q & 1 else -GAUSS
        e1 = GAUSS if (q >> 1) & 1 else -GAUSS
        e2 = GAUSS if (q >> 2) & 1 else -GAUSS
        # columns of J = ∂x/∂ξ
        a0 = x1 + x12 * e1 + x13 * e2 + x123 * e1 * e2
        a1 = y1 + y12 * e1 + y13 * e2 + y123 * e1 * e2
        a2 = z1 + z12 * e1 + z13 * e2 + z123 * e1 * e2
        b0 = x2 + x12 * e0 + x23 * e2 + x123 * e0 * e2
        b1 = y2 + y12 * e0 + y23 * e2 + y123 * e0 * e2
        b2 = z2 + z12 * e0 + z23 * e2 + z123 * e0 * e2
        c0 = x3 + x13 * e0 + x23 * e1 + x123 * e0 * e1
        c1 = y3 + y13 * e0 + y23 * e1 + y123 * e0 * e1
        c2 = z3 + z13 * e0 + z23 * e1 + z123 * e0 * e1
        # cofactor columns k1 = b × c, k2 = c × a, k3 = a × b; det = a · k1
        k1x, k1y, k1z = b1 * c2 - b2 * c1, b2 * c0 - b0 * c2, b0 * c1 - b1 * c0
        k2x, k2y, k2z = c1 * a2 - c2 * a1, c2 * a0 - c0 * a2, c0 * a1 - c1 * a0
        k3x, k3y, k3z = a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0
        det = a0 * k1x + a1 * k1y + a2 * k1z
        vol += det
        for al in range(8):
            add_point_weights(sc, al, det, (k1x, k1y, k1z, k2x, k2y, k2z, k3x, k3y, k3z),
                              (SHAPES[q, al, 0], SHAPES[q, al, 1], SHAPES[q, al, 2],
                               SHAPES[q, al, 3]))
    normalise_weights(sc, 8, vol)
    return vol


@helper_kernel
def support(i, frame, slot, shape, fields):
    """Particle ``i``'s capped corners and weights into the scratch ``sc`` and its corners' local
    cells and fractions into ``cells``, ``fr`` (the stencil is the scratch, ``shape``); code −2
    (inverted: nothing located) or −1 (a corner's nodes leave the box)."""
    lcr, sc, cells, fr, _ = shape
    x = fields.x
    cap_corners(3, fields.corners[i], lcr, sc)
    V = hex_weights(sc)
    if not V > 0.0:
        return -2, shape
    ox, oy, oz, ihx, ihy, ihz, _, _ = frame
    bx, by, bz, jlx, jly, jlz, jhx, jhy, jhz = slot
    o, ih = (ox, oy, oz), (ihx, ihy, ihz)
    base, jlo, jhi = (bx, by, bz), (jlx, jly, jlz), (jhx, jhy, jhz)
    ok = True
    for a in range(8):
        for k in range(3):
            j, f = cell_of((x[i, k] - o[k]) * ih[k] + sc[a, k] * ih[k], base[k], jlo[k], jhi[k])
            cells[a, k] = j
            fr[a, k] = f
            ok = ok and j >= 0
    return (0 if ok else -1), shape


@helper_kernel
def scatter(i, g, frame, st, fields, args):
    """Mass, momentum and force of particle ``i``, corner by corner."""
    v, mass = fields.v, fields.mass
    bforce, forced = args
    L0, L01 = frame[6], frame[7]
    _, sc, cells, fr, _ = st
    t00, t01, t02, t10, t11, t12, t20, t21, t22 = volume_stress(i, fields)
    m = mass[i]
    vx, vy, vz = v[i, 0], v[i, 1], v[i, 2]
    bfx, bfy, bfz = body_force(bforce, forced, i, m)
    for a in range(8):
        wf, gx, gy, gz = sc[a, WF], sc[a, WG], sc[a, WG + 1], sc[a, WG + 2]
        mw = m * wf
        scatter7(g, L0, L01, cells[a, 0], cells[a, 1], cells[a, 2], fr[a, 0], fr[a, 1],
                 fr[a, 2], mw, mw * vx, mw * vy, mw * vz,
                 bfx * wf - (t00 * gx + t01 * gy + t02 * gz),
                 bfy * wf - (t10 * gx + t11 * gy + t12 * gz),
                 bfz * wf - (t20 * gx + t21 * gy + t22 * gz))


@helper_kernel
def scatter_momentum(i, g, frame, st, fields, args):
    """Momentum of particle ``i``, corner by corner."""
    v, mass = fields.v, fields.mass
    L0, L01 = frame[6], frame[7]
    _, sc, cells, fr, _ = st
    m = mass[i]
    for a in range(8):
        mw = m * sc[a, WF]
        scatter_mv(g, L0, L01, cells[a, 0], cells[a, 1], cells[a, 2], fr[a, 0], fr[a, 1],
                   fr[a, 2], mw * v[i, 0], mw * v[i, 1], mw * v[i, 2])


@helper_kernel
def gather(step, i, g, frame, st, shape, fields):
    """``v_p = Σ wf_α v(x_α)``, ``Δv_p`` alike and ``Δt L`` at particle ``i``; the corners'
    velocities (scratch ``u`` of ``shape``) go on to :func:`follow`."""
    dt = step[1]
    L0, L01 = frame[6], frame[7]
    _, sc, cells, fr, _ = st
    u = shape[4]
    vx = vy = vz = dvx = dvy = dvz = 0.0
    l00 = l01 = l02 = l10 = l11 = l12 = l20 = l21 = l22 = 0.0
    for a in range(8):
        u0, u1, u2, u3, u4, u5 = gather6(g, L0, L01, cells[a, 0], cells[a, 1],
                                         cells[a, 2], fr[a, 0], fr[a, 1], fr[a, 2])
        u[a, 0], u[a, 1], u[a, 2] = u0, u1, u2
        wf, gx, gy, gz = sc[a, WF], sc[a, WG], sc[a, WG + 1], sc[a, WG + 2]
        vx += wf * u0
        vy += wf * u1
        vz += wf * u2
        dvx += wf * u3
        dvy += wf * u4
        dvz += wf * u5
        l00 += u0 * gx
        l01 += u0 * gy
        l02 += u0 * gz
        l10 += u1 * gx
        l11 += u1 * gy
        l12 += u1 * gz
        l20 += u2 * gx
        l21 += u2 * gy
        l22 += u2 * gz
    return ((vx, vy, vz), (dvx, dvy, dvz), ZERO9,
            (dt * l00, dt * l01, dt * l02, dt * l10, dt * l11, dt * l12, dt * l20, dt * l21,
             dt * l22), (u, vx, vy, vz))


@helper_kernel
def follow(i, dt, extra, fields):
    """Move particle ``i``'s tracked corners with the grid, ``c_α += Δt (v(x_α) − v_p)``, unless
    its domain is frozen."""
    c, rf = fields.corners, fields.rf
    u, vx, vy, vz = extra
    if rf[i, 0, 0] == 0.0 and rf[i, 1, 0] == 0.0 and rf[i, 2, 0] == 0.0:  # not frozen
        for a in range(8):
            c[i, a, 0] += dt * (u[a, 0] - vx)
            c[i, a, 1] += dt * (u[a, 1] - vy)
            c[i, a, 2] += dt * (u[a, 2] - vz)


@kernel
def p2g_cpdi2(lcr, boxes, order, fields, bforce, gsum, err):
    """Mass, momentum and force rows of ``gsum[slot]`` from every slot's particles."""
    _p2g_loop(boxes, order, fields, bforce, gsum, err, _scratch(lcr))


@loop_kernel
def _p2g_loop(boxes, order, fields, bforce, gsum, err, shape):
    gsum[:] = 0.0
    each_particle(support, scatter, boxes, order, gsum, err, shape, fields,
                  (bforce, bforce.shape[0] > 0))


@kernel
def p2g_momentum_cpdi2(lcr, boxes, order, fields, gsum, err):
    """The MUSL re-map: momentum rows (1, 2, 3) of ``gsum`` only."""
    _p2g_momentum_loop(boxes, order, fields, gsum, err, _scratch(lcr))


@loop_kernel
def _p2g_momentum_loop(boxes, order, fields, gsum, err, shape):
    gsum[:, 1:4, :] = 0.0
    each_particle(support, scatter_momentum, boxes, order, gsum, err, shape, fields, None)


@kernel
def g2p_cpdi2(mode, lcr, boxes, order, dt, flip, fields, material, gnew, err, locate):
    """G2P in one of the three modes, moving the tracked corners in USL and MUSL's deformation
    pass; returns (largest ``c_p + |v_p|`` when the stress is updated, particles that changed
    patch, first particle off the grid)."""
    return _g2p_loop(mode, boxes, order, dt, flip, fields, material, gnew, err, locate,
                     _scratch(lcr))


@loop_kernel
def _g2p_loop(mode, boxes, order, dt, flip, fields, material, gnew, err, locate, shape):
    return each_particle_g2p(support, gather, follow, (mode, dt, flip, False), boxes, order, gnew,
                             err, locate, shape, fields, material)
