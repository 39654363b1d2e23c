"""One entry point for every interpolator: the (node, weight, gradient) entries of a particle.

``particle_support`` dispatches on the interpolator's code, given as a tuple of that length
(:data:`parmpm.shapes.KINDS`: numba cannot cache kernels that take functions as arguments, so the
registry in :mod:`parmpm.shapes` maps names to codes and this is the single switch; a length is a
compile-time constant, so each loop compiles one branch). Tensor-product interpolators (mpm, ugimp, cpgimp, bspline) fill per-axis rows
``(jk, wk, dwk)`` and are assembled here; cpdi and cpdi2 write their corner entries directly.

Entries: ``idx[e]`` flat local node index in the patch's ghost-inclusive box, ``w[e] = φ_ip``,
``g[e, :] = ∇φ_ip`` (physical units). A return of -1 (``OUT_OF_BOX``) means the particle reaches
a node outside the grid or beyond the patch's ghost layer; -2 (``INVERTED``, cpdi2 only) that
its domain's volume is not positive (:mod:`parmpm.shapes.cpdi2`).
"""
from parmpm.core.jit import helper_kernel
from parmpm.core.records import NO_SCALING
from parmpm.shapes import BSPLINE, CPDI, CPDI2, CPGIMP, MPM
from parmpm.shapes.bspline import bspline_axis
from parmpm.shapes.cpdi import cpdi_support
from parmpm.shapes.cpdi2 import INVERTED, OUT_OF_BOX, cpdi2_support  # noqa: F401 (re-exported)
from parmpm.shapes.gimp import gimp_axis
from parmpm.shapes.hat import mpm_axis
from parmpm.shapes.scaling import scale_domain


@helper_kernel
def _tensor_entries(d, L0, L1, nk, jk, wk, dwk, idx, w, g):
    n1 = nk[1] if d > 1 else 1
    n2 = nk[2] if d > 2 else 1
    n = 0
    for i2 in range(n2):
        w2 = wk[2, i2] if d > 2 else 1.0
        d2 = dwk[2, i2] if d > 2 else 0.0
        o2 = jk[2, i2] if d > 2 else 0
        for i1 in range(n1):
            w1 = wk[1, i1] if d > 1 else 1.0
            d1 = dwk[1, i1] if d > 1 else 0.0
            o1 = jk[1, i1] if d > 1 else 0
            for i0 in range(nk[0]):
                w0 = wk[0, i0]
                idx[n] = jk[0, i0] + L0 * (o1 + L1 * o2)
                w[n] = w0 * w1 * w2
                g[n, 0] = dwk[0, i0] * w1 * w2
                g[n, 1] = w0 * d1 * w2
                g[n, 2] = w0 * w1 * d2
                n += 1
    return n


@helper_kernel
def domain_matrix(d, method, lcr, F, r0, R):
    """CPDI domain ``R = F·R0`` (3×3 scratch, leading d×d block), then capped at ``lcr`` when
    domain scaling is on (``lcr`` finite). Other interpolators leave R untouched."""
    if method != CPDI:
        return
    for a in range(3):
        for b in range(3):
            R[a, b] = 0.0
    for a in range(d):
        for b in range(d):
            acc = 0.0
            for k in range(d):
                acc += F[a, k] * r0[k, b]
            R[a, b] = acc
    if lcr < NO_SCALING:  # a cap no vector reaches changes nothing: skip it
        scale_domain(d, R, lcr)


@helper_kernel
def particle_support(kind, d, xi, F, lh0, R, C, base, nloc, nglob, inv_h,
                     nk, jk, wk, dwk, idx, w, g, corners, i, lcr, sc):
    """Entries of one particle of the interpolator ``kind`` (:data:`parmpm.shapes.KINDS`: the
    branches of the others are pruned before they are compiled); ``xi`` grid coordinates, ``F`` its deformation gradient, ``lh0``
    its initial GIMP half-widths (physical), ``R`` its (already scaled) CPDI domain;
    ``corners[i]`` its CPDI2 corners (``corners`` the field of every particle: empty unless
    cpdi2), capped at ``lcr`` into the scratch ``sc`` (:data:`parmpm.shapes.cpdi2.SCRATCH_SHAPE`,
    where the capped corners stay for the caller). Returns the entry count, ``OUT_OF_BOX`` (-1:
    reach beyond the ghost layer / grid) or ``INVERTED`` (-2: a cpdi2 domain of volume <= 0)."""
    if len(kind) == CPDI:
        return cpdi_support(d, xi, R, C, base, nloc, nglob, inv_h, nloc[0], nloc[1],
                            jk, wk, dwk, idx, w, g)
    if len(kind) == CPDI2:
        return cpdi2_support(d, xi, corners[i], lcr, base, nloc, nglob, inv_h, nloc[0], nloc[1],
                             jk, wk, dwk, idx, w, g, sc)
    for k in range(d):
        if len(kind) == MPM:
            nk[k] = mpm_axis(xi[k], base[k], nloc[k], nglob[k], inv_h[k], jk, wk, dwk, k)
        elif len(kind) == BSPLINE:
            nk[k] = bspline_axis(xi[k], base[k], nloc[k], nglob[k], inv_h[k], jk, wk, dwk, k)
        else:
            half = lh0[k] * inv_h[k]
            if len(kind) == CPGIMP:
                half *= abs(F[k, k])
            nk[k] = gimp_axis(xi[k], half, base[k], nloc[k], nglob[k], inv_h[k], jk, wk, dwk, k)
        if nk[k] < 0:
            return -1
    return _tensor_entries(d, nloc[0], nloc[1], nk, jk, wk, dwk, idx, w, g)
