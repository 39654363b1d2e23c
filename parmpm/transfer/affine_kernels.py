"""The affine pieces of the generic transfers (:mod:`parmpm.transfer.generic`): APIC's affine momentum
and MLS's gradient (:mod:`parmpm.transfer.affine` has the equations), over one particle's support entries.

They read and write the generic loops' per-call scratch (:func:`parmpm.transfer.generic.loop_scratch`): the
grid coordinates ``xi`` (2), the entries' nodes ``idx`` (7), weights ``w`` (8) and gradients
``g`` (9), and the offsets ``r`` (12) that :func:`offsets` fills.
"""
from parmpm.core.jit import helper_kernel


@helper_kernel
def offsets(d, boxes, p, n, scratch):
    """``r[e] = x_i − x_p`` (physical units) of the ``n`` entries of the particle whose grid
    coordinates are in the scratch's ``xi`` (APIC's affine terms). An entry's node is its index
    modulo the box's node count: crack faces stack the fields' copies of the box that far apart
    (:func:`parmpm.grid.crack.to_fields`)."""
    xi, idx, r = scratch[2], scratch[7], scratch[12]
    base, nloc, inv_h = boxes.base, boxes.nloc, boxes.inv_h
    box = nloc[0] * nloc[1] * nloc[2]
    for e in range(n):
        loc = idx[e] % box
        r[e, 0] = (base[p, 0] + loc % nloc[0] - xi[0]) / inv_h[0]
        if d > 1:
            r[e, 1] = (base[p, 1] + (loc // nloc[0]) % nloc[1] - xi[1]) / inv_h[1]
        if d > 2:
            r[e, 2] = (base[p, 2] + loc // (nloc[0] * nloc[1]) - xi[2]) / inv_h[2]


@helper_kernel
def affine_scatter(d, n, m, vi, Ci, gmv, p, scratch):
    """APIC P2G momentum: ``(m v)_i += m φ_ip (v_p + C_p r_e)`` over the ``n`` entries."""
    idx, w, r = scratch[7], scratch[8], scratch[12]
    for e in range(n):
        mw = m * w[e]
        for a in range(d):
            s = vi[a]
            for b in range(d):
                s += Ci[a, b] * r[e, b]
            gmv[p, idx[e], a] += mw * s


@helper_kernel
def mls_gradients(d, n, inv_h, scratch):
    """MLS: replace the entries' weight gradients by ``φ D⁻¹ r`` (``D⁻¹ = diag(4/Δx²)``, the
    offsets ``r`` from :func:`offsets`)."""
    w, g, r = scratch[8], scratch[9], scratch[12]
    for e in range(n):
        for b in range(d):
            g[e, b] = w[e] * (4.0 * inv_h[b] * inv_h[b]) * r[e, b]


@helper_kernel
def affine_gather(d, n, gvel, p, inv_h, vi, Ci, scratch):
    """APIC G2P: ``v_p = Σ φ v_i``, ``C_p = Σ φ v_i ⊗ r · D⁻¹`` with the B-spline's
    ``D⁻¹ = diag(4/Δx²)`` (:mod:`parmpm.transfer.affine`)."""
    idx, w, r = scratch[7], scratch[8], scratch[12]
    for a in range(d):
        s = 0.0
        for e in range(n):
            s += w[e] * gvel[p, idx[e], a]
        vi[a] = s
        for b in range(d):
            s = 0.0
            for e in range(n):
                s += w[e] * gvel[p, idx[e], a] * r[e, b]
            Ci[a, b] = s * (4.0 * inv_h[b] * inv_h[b])
