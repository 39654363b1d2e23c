"""The particle passes that find which side of a crack each particle is on
(:mod:`parmpm.grid.crack` has the method): the damage field's P2G, and each particle's damage
gradient gathered from it with its contribution to the nodes' crack normals scattered at once.

Both walk the particles as the generic transfers do (:func:`parmpm.transfer.generic.each_particle`,
patch by patch in canonical order), so every node's sums are the same on any number of ranks.
"""
from parmpm.core.jit import helper_kernel, kernel, loop_kernel
from parmpm.transfer.generic import each_particle, loop_scratch, zero_node_major


@kernel
def damage_sums(how, boxes, fields, damage, sums, dmax, err):
    """``sums`` (node-major, rows ``Σ S m``, ``Σ S m D``) and ``dmax`` (the largest ``D`` of a
    particle of nonzero weight) of this rank's patch slots (zeroed here)."""
    _damage_sums_loop(how, boxes, boxes.order, fields, damage, (sums, dmax), err,
                      loop_scratch(boxes.nloc, len(how.axes)))


@loop_kernel
def _damage_sums_loop(how, boxes, order, fields, damage, out, err, scratch):
    sums, dmax = out
    zero_node_major(sums)
    zero_node_major(dmax)
    each_particle(_damage_one, len(how.axes), how, boxes, order, fields, err, scratch, out, damage, 0,
                  None)


@helper_kernel
def _damage_one(i, p, n, d, how, boxes, fields, scratch, out, damage, acc):
    sums, dmax = out
    idx, w = scratch[7], scratch[8]
    m = fields.mass[i]
    D = damage[i]
    for e in range(n):
        node = idx[e]
        mw = m * w[e]
        sums[p, node, 0] += mw
        sums[p, node, 1] += mw * D
        if w[e] > 0.0 and D > dmax[p, node, 0]:
            dmax[p, node, 0] = D
    return acc


@kernel
def damage_gradients(how, boxes, fields, dnode, grad, tsum, err):
    """Every particle's damage gradient ``grad[i] = Σ D_i ∇S_ip`` from the nodal damage
    ``dnode`` (node-major, one row), and ``tsum`` (node-major, zeroed here): rows ``Σ S m g``
    then the upper triangle of ``Σ S m g gᵀ``."""
    _gradients_loop(how, boxes, boxes.order, fields, dnode, (grad, tsum), err,
                    loop_scratch(boxes.nloc, len(how.axes)))


@loop_kernel
def _gradients_loop(how, boxes, order, fields, dnode, out, err, scratch):
    zero_node_major(out[1])
    each_particle(_gradient_one, len(how.axes), how, boxes, order, fields, err, scratch, out, dnode,
                  0, None)


@helper_kernel
def _gradient_one(i, p, n, d, how, boxes, fields, scratch, out, dnode, acc):
    grad, tsum = out
    idx, w, g = scratch[7], scratch[8], scratch[9]
    for a in range(3):
        grad[i, a] = 0.0
    for e in range(n):
        Di = dnode[p, idx[e], 0]
        for a in range(d):
            grad[i, a] += Di * g[e, a]
    m = fields.mass[i]
    for e in range(n):
        node = idx[e]
        mw = m * w[e]
        for a in range(d):
            tsum[p, node, a] += mw * grad[i, a]
        r = d
        for a in range(d):
            for b in range(a, d):
                tsum[p, node, r] += mw * grad[i, a] * grad[i, b]
                r += 1
    return acc
