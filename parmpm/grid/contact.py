"""Multi-velocity-field contact on the grid (Bardenhagen et al. 2000, 2001): bodies in separate
fields meet at the nodes both reach, and only there does anything happen.

Every field ``k`` has its own mass ``m_k``, momentum, force and updated velocity ``v_k`` at a
node, and its own first moment ``X_k = Σ_p S_ip m_p x_p`` (P2G's momentum scatter with positions
for velocities). At a node where two or more fields have mass:

* **normal** (``contact_normals``, ``[contact] normal``): by default ("separating") two
  candidates, out of the field with the most mass at the node (``−D_h``, ``D_h = X_h − m_h x_i``
  its first moment about the node: Nairn's "larger volume gradient" choice, with a moment for
  the gradient) and the line between the fields' local centres of mass; ``contact_correct``
  takes the one along which the fields are separated most (the larger gap, below). The heavy
  field's normal is right at the corner of a block sliding on another, where the centre line
  tilts and turns the slide into approach; the centre line is right between two curved bodies,
  where the heavy field's surface normal turns away from the contact point. With two fields the
  normals are opposite, so both agree on the plane. For comparisons a scene can ask for one
  normal alone: "heavy", "centroids", "gradient" (out of the field whose moment points at the
  others most: the moment's size is Nairn's volume gradient, its direction keeps a block's
  free front face from deciding the normal of the contact beneath it) or "average"
  (``Σ_{j≠k} D_j − D_k``, Nairn's average volume gradient; it tilts at a body's corners).
* **separation** (``contact_extents``, ``[contact] gap``): along each candidate ``n_k``, the
  farthest point of field ``k``'s particle domains near the node (``max x_p·n + e_p``,
  ``e_p = Σ_j |r_pj·n|`` the domain's half-extent, ``r = F r0``) and the nearest point of the
  other fields' (``min x_p·n − e_p``); the gap is their difference (Nairn et al. 2018: the
  closest particles decide). A node whose fields have a gap is not in contact whatever their
  velocities: bodies touch when their domains meet, not when their supports first overlap a
  cell or more earlier (Bardenhagen's approach test alone). By default ("column") only the
  particles in the node's column across the normal count (as for walls): along a normal a few
  degrees off the line between two disks, particles a cell above and below the node spread the
  projections and closed a gap half a cell early. With "line" only the domains the node's own
  line crosses count, and only their stretch on the line
  (:func:`parmpm.grid.near.line_span`): the surfaces' distance at the node itself, so a node a
  cell from where a disk touches a flat sees the disk's surface ``s²/2R`` above it
  (docs/concepts/contact.md compares the two).
  The extremes are per-node maxima, combined over the ghost layers by a maximum, the same on
  any number of ranks.
* **correction** (``contact_correct``): with ``v_c = Σ m_j v_j / Σ m_j`` the node's centre-of-mass
  velocity and ``Δ = (v_k − v_c)·n_k > 0`` (field ``k`` approaches the others), the normal part
  goes and Coulomb friction acts on the tangential part ``t = v_k − v_c − Δ n_k``:

      stick  if |t| ≤ μ Δ:   v_k ← v_c
      slip   otherwise:       v_k ← v_k − Δ n_k − μ Δ t/|t|

  With two fields ``m_a (v_a − v_c) = −m_b (v_b − v_c)``, so the corrections are equal and
  opposite: momentum is kept to round-off. Fields that separate (``Δ ≤ 0``) move freely.
  ``m_k (v_k' − v_k)`` is the contact impulse on field ``k``; the change of ``½ m_k |v_k|²``,
  less what the forces' and gravity's work gain over the corrected mean velocity (as for walls,
  :mod:`parmpm.grid.walls`), is the contact's share of the energy ledger: friction's work on a
  slide; during a hard impact an accounting share that can be positive.

``docs/concepts/contact.md`` derives it and reports what was measured.
"""
import numpy as np

from parmpm.core.jit import helper_kernel, kernel
from parmpm.grid.crack import pair_field
from parmpm.grid.near import domain_vectors, half_extent, line_span, node_box


#: ``[contact] normal`` → the mode :func:`contact_normals` takes
NORMAL_MODES = {"separating": 0, "heavy": 1, "centroids": 2, "gradient": 3, "average": 4}
SEPARATING, HEAVY, CENTROIDS, GRADIENT, AVERAGE = range(5)
#: ``[contact] gap`` → the mode :func:`contact_extents` takes
GAP_MODES = {"column": 0, "line": 1}
COLUMN, LINE = range(2)


@helper_kernel
def centroid_line(d, sums, X, eps, p, node, k, c):
    """Into ``c``: the line from field ``k``'s local centre of mass to the other fields'
    (those with mass over ``eps``), not normalised; returns its squared length."""
    K = sums.shape[0]
    rest = 0.0
    for a in range(d):
        c[a] = 0.0
    for j in range(K):
        mj = sums[j, p, 0, node]
        if j != k and mj > eps:
            rest += mj
            for a in range(d):
                c[a] += X[j, p, 1 + a, node]
    mk = sums[k, p, 0, node]
    size = 0.0
    for a in range(d):
        c[a] = c[a] / rest - X[k, p, 1 + a, node] / mk
        size += c[a] * c[a]
    return size


@helper_kernel
def deciding_field(d, sums, X, eps, p, node, xi, c):
    """"gradient": the field whose moment about the node points at the others most,
    ``max_k −D_k·u_k`` (``u_k`` the unit line from its local centre of mass to the others'):
    the magnitude is Nairn's volume gradient, the direction keeps a field's free surface beside
    the node (a block's front face at its corner) from deciding the normal of the contact
    beneath. ``c``: (3,) scratch."""
    K = sums.shape[0]
    best = -np.inf
    out = 0
    for k in range(K):
        mk = sums[k, p, 0, node]
        if not mk > eps:
            continue
        uu = centroid_line(d, sums, X, eps, p, node, k, c)
        score = 0.0
        for a in range(d):
            score -= (X[k, p, 1 + a, node] - mk * xi[a]) * c[a]
        score = score / np.sqrt(uu) if uu > 0.0 else 0.0
        if score > best:
            best = score
            out = k
    return out


@helper_kernel
def average_normal(d, sums, X, eps, p, node, xi, k, c):
    """"average": field ``k``'s unit normal ``∝ Σ_{j≠k} D_j − D_k`` into ``c`` (zero where
    the moments cancel), the moments' counterpart of Nairn's average volume gradient."""
    K = sums.shape[0]
    size = 0.0
    for a in range(d):
        c[a] = -(X[k, p, 1 + a, node] - sums[k, p, 0, node] * xi[a])
        for j in range(K):
            mj = sums[j, p, 0, node]
            if j != k and mj > eps:
                c[a] += X[j, p, 1 + a, node] - mj * xi[a]
        size += c[a] * c[a]
    size = np.sqrt(size)
    for a in range(d):
        c[a] = c[a] / size if size > 0.0 else 0.0


@helper_kernel
def fields_meet(sums, eps, p, node):
    """Two or more fields have mass (more than ``eps``) at node ``node`` of slot ``p``: where
    contact acts (``sums``: (fields, slots, rows, stride), row 0 the mass)."""
    present = 0
    for k in range(sums.shape[0]):
        if sums[k, p, 0, node] > eps:
            present += 1
    return present >= 2


@kernel
def contact_mask(nodes, sums, eps, mask):
    """``mask[p, 0, node]`` 1 at every owned node where fields meet (:func:`fields_meet`),
    else 0: the nodes :func:`contact_normals` gives normals (``sums``: as there)."""
    own_lo, own_hi, base, nloc, face_lo, face_hi = nodes
    L0, L1 = nloc[0], nloc[1]
    for p in range(own_lo.shape[0]):
        for i2 in range(own_lo[p, 2], own_hi[p, 2]):
            for i1 in range(own_lo[p, 1], own_hi[p, 1]):
                row0 = L0 * (i1 + L1 * i2)
                for i0 in range(own_lo[p, 0], own_hi[p, 0]):
                    node = row0 + i0
                    mask[p, 0, node] = 1.0 if fields_meet(sums, eps, p, node) else 0.0


@kernel
def contact_normals(d, nodes, origin, h, sums, X, eps, mode, normal, mask, marked):
    """``normal[k, p, :2d, node]``: field ``k``'s candidate contact normals at every owned
    node where it and another field have mass (more than ``eps``), zero for a field without
    (``mode``: :data:`NORMAL_MODES`): rows ``0..d−1`` out of the heavy field ("separating",
    "heavy"), out of the deciding field ("gradient") or the moments' average ("average"); rows
    ``d..2d−1`` the line between the centres of mass ("separating", "centroids");
    ``mask[p, 0, node]`` 1 at those nodes, else 0 (``marked``: :func:`contact_mask` has marked
    them already, on the same sums: read, not written). Elsewhere the normals keep what they held:
    every reader (the extents, the correction) looks at the nodes the mask marks only.
    ``sums``: (fields, slots, rows, stride) P2G sums (row 0 the mass); ``X``: (fields, slots,
    1 + d, stride) first moments in rows 1..d (spare slots past the patches' are not visited)."""
    own_lo, own_hi, base, nloc, face_lo, face_hi = nodes
    K = sums.shape[0]
    L0, L1 = nloc[0], nloc[1]
    c = np.zeros(3)
    e = np.zeros(3)
    xi = np.zeros(3)
    for p in range(own_lo.shape[0]):
        for i2 in range(own_lo[p, 2], own_hi[p, 2]):
            xi[2] = origin[2] + (base[p, 2] + i2) * h[2]
            for i1 in range(own_lo[p, 1], own_hi[p, 1]):
                xi[1] = origin[1] + (base[p, 1] + i1) * h[1]
                row0 = L0 * (i1 + L1 * i2)
                for i0 in range(own_lo[p, 0], own_hi[p, 0]):
                    xi[0] = origin[0] + (base[p, 0] + i0) * h[0]
                    node = row0 + i0
                    if marked:
                        if mask[p, 0, node] == 0.0:
                            continue
                    elif fields_meet(sums, eps, p, node):
                        mask[p, 0, node] = 1.0
                    else:
                        mask[p, 0, node] = 0.0
                        continue
                    for k in range(K):
                        for a in range(2 * d):
                            normal[k, p, a, node] = 0.0
                    heavy = 0  # the field with the most mass here (ties: the first)
                    for k in range(1, K):
                        if sums[k, p, 0, node] > sums[heavy, p, 0, node]:
                            heavy = k
                    if mode == GRADIENT:
                        heavy = deciding_field(d, sums, X, eps, p, node, xi, e)
                    mh = sums[heavy, p, 0, node]
                    size = 0.0
                    for a in range(d):  # candidate 0: out of the heavy field, −D_heavy
                        c[a] = mh * xi[a] - X[heavy, p, 1 + a, node]
                        size += c[a] * c[a]
                    if not size > 0.0 and mode != CENTROIDS and mode != AVERAGE:
                        continue  # the node at the heavy field's centre: no side to tell
                    size = np.sqrt(size)
                    for k in range(K):
                        mk = sums[k, p, 0, node]
                        if not mk > eps:
                            continue
                        if mode == AVERAGE:
                            average_normal(d, sums, X, eps, p, node, xi, k, e)
                            for a in range(d):
                                normal[k, p, a, node] = e[a]
                            continue
                        if mode != CENTROIDS:
                            sign = 1.0 if k == heavy else -1.0
                            for a in range(d):
                                normal[k, p, a, node] = sign * c[a] / size
                        if mode == HEAVY or mode == GRADIENT:
                            continue
                        # candidate 1: from field k's centre of mass to the others'
                        size2 = centroid_line(d, sums, X, eps, p, node, k, e)
                        if size2 > 0.0:
                            size2 = np.sqrt(size2)
                            for a in range(d):
                                normal[k, p, d + a, node] = e[a] / size2


@kernel
def contact_extents(d, start, order, field, x, F, r0, origin, h, reach, base, nloc, normal,
                    mask, active, ext, sides, gap):
    """For every node near a particle (within its domain's axis extent plus ``reach`` cells)
    with contact normals, over the particles in the node's column (their distance from the node
    across ``n_k`` at most half a cell, 2D, or half a face diagonal, 3D, plus their domain's
    longest half-vector), for each candidate normal ``c`` (0, 1): ``ext[k, p, 2c, node]`` the
    largest ``x·n_k + e`` of field ``k``'s particles, ``ext[k, p, 2c + 1, node]`` the largest
    ``−(x·n_k − e)`` of the other fields' (the caller sets them to −inf first); ``field``: each
    physical row's field, or with crack ``sides`` (:data:`parmpm.core.records.Sides`) its
    field at each node (:func:`parmpm.grid.crack.pair_field`). Only slots with a contact node
    (``active``) and the nodes marked in ``mask`` are visited: the rest of the grid costs one
    test per slot or node. ``gap`` "line" (:data:`GAP_MODES`): only the domains the node's own
    line along ``n_k`` crosses count, with the stretch on the line
    (:func:`parmpm.grid.near.line_span`) for ``x·n ± e``."""
    K = normal.shape[0]
    r = np.zeros((3, 3))
    inv = np.zeros((3, 3))
    q = np.zeros(3)
    lo = np.zeros(3, np.int64)
    hi = np.zeros(3, np.int64)
    hmin = h[0]
    for a in range(1, d):
        hmin = min(hmin, h[a])
    column = 0.5 * np.sqrt(d - 1.0) * hmin
    for p in range(start.size - 1):
        if not active[p]:
            continue
        for kk in range(start[p], start[p + 1]):
            i = order[kk]
            domain_vectors(d, F, r0, i, r)
            size = 0.0  # the domain's longest half-vector: how far it reaches across
            for j in range(d):
                rj = 0.0
                for a in range(d):
                    rj += r[a, j] * r[a, j]
                size = max(size, np.sqrt(rj))
            node_box(d, x, i, r, reach, origin, h, base[p], nloc, lo, hi)
            for i2 in range(lo[2], hi[2] + 1):
                for i1 in range(lo[1], hi[1] + 1):
                    for i0 in range(lo[0], hi[0] + 1):
                        node = i0 + nloc[0] * (i1 + nloc[1] * i2)
                        if mask[p, 0, node] == 0.0:
                            continue
                        f = pair_field(sides, field, i, p, node)
                        qq = 0.0
                        for a in range(d):
                            ia = i0 if a == 0 else (i1 if a == 1 else i2)
                            q[a] = x[i, a] - origin[a] - (base[p, a] + ia) * h[a]
                            qq += q[a] * q[a]
                        for k in range(K):
                            for cand in range(2):
                                o = cand * d
                                s = 0.0
                                nn = 0.0
                                qn = 0.0
                                for a in range(d):
                                    s += x[i, a] * normal[k, p, o + a, node]
                                    qn += q[a] * normal[k, p, o + a, node]
                                    nn += normal[k, p, o + a, node] * normal[k, p, o + a, node]
                                if nn == 0.0:
                                    continue
                                if gap == LINE:  # x·n of the line's ends in the domain
                                    t_lo, t_hi = line_span(d, r, q, normal[k, p, o:o + d, node],
                                                           inv)
                                    if t_lo > t_hi:
                                        continue  # the node's line misses this domain
                                    if k == f:
                                        ext[k, p, 2 * cand, node] = max(
                                            ext[k, p, 2 * cand, node], s - qn + t_hi)
                                    else:
                                        ext[k, p, 2 * cand + 1, node] = max(
                                            ext[k, p, 2 * cand + 1, node], qn - s - t_lo)
                                    continue
                                if qq - qn * qn > (column + size) * (column + size):
                                    continue  # not in the node's column across the plane
                                e = half_extent(d, r, normal[k, p, o:o + d, node])
                                if k == f:
                                    ext[k, p, 2 * cand, node] = max(ext[k, p, 2 * cand, node],
                                                                    s + e)
                                else:
                                    ext[k, p, 2 * cand + 1, node] = max(
                                        ext[k, p, 2 * cand + 1, node], e - s)


@kernel
def contact_correct(d, nodes, sums, new, normal, ext, mu, dt, gvec, heavy, eps, momentum_only,
                    mode, mask):
    """Correct every field's updated velocity (``new[k]``: rows ``v``, then ``Δv`` unless
    ``momentum_only``) at the owned nodes where fields touch (``mask``: where they meet, from
    :func:`contact_normals` on these masses) and approach; returns per slot and
    field: the contact impulse on the field (3), its work, and what the forces' and gravity's
    work gain at the corrected mean velocity (the energy ledger's account, as for walls;
    ``heavy``: the lightest node whose force row counts)."""
    own_lo, own_hi, base, nloc, face_lo, face_hi = nodes
    K = sums.shape[0]
    out = np.zeros((own_lo.shape[0], K, 6))
    L0, L1 = nloc[0], nloc[1]
    vc = np.zeros(3)
    t = np.zeros(3)
    fix = np.zeros((K, 3))
    for p in range(own_lo.shape[0]):
        for i2 in range(own_lo[p, 2], own_hi[p, 2]):
            for i1 in range(own_lo[p, 1], own_hi[p, 1]):
                row0 = L0 * (i1 + L1 * i2)
                for i0 in range(own_lo[p, 0], own_hi[p, 0]):
                    node = row0 + i0
                    if mask[p, 0, node] == 0.0:
                        continue
                    M = 0.0
                    for a in range(d):
                        vc[a] = 0.0
                    for k in range(K):
                        m = sums[k, p, 0, node]
                        if m > eps:
                            M += m
                            for a in range(d):
                                vc[a] += m * new[k, p, a, node]
                    for a in range(d):
                        vc[a] /= M
                    for k in range(K):  # every field's change first, from the same v_c
                        for a in range(d):
                            fix[k, a] = 0.0
                        if not sums[k, p, 0, node] > eps:
                            continue
                        # the candidate normal that separates the fields best (the larger
                        # gap, min(other) − max(own)); ties and a missing second: the first
                        g0 = -(ext[k, p, 0, node] + ext[k, p, 1, node])
                        g1 = -(ext[k, p, 2, node] + ext[k, p, 3, node])
                        o = d if g1 > g0 else 0
                        if mode != SEPARATING:  # one candidate
                            o = d if mode == CENTROIDS else 0
                            g0 = g1 = g1 if mode == CENTROIDS else g0
                        if max(g0, g1) > 0.0:
                            continue  # a gap along the better normal: not touching
                        dn = 0.0
                        nn = 0.0
                        for a in range(d):
                            dn += (new[k, p, a, node] - vc[a]) * normal[k, p, o + a, node]
                            nn += normal[k, p, o + a, node] * normal[k, p, o + a, node]
                        if nn == 0.0 or not dn > 0.0:
                            continue
                        slide = 0.0
                        for a in range(d):
                            t[a] = new[k, p, a, node] - vc[a] - dn * normal[k, p, o + a, node]
                            slide += t[a] * t[a]
                        slide = np.sqrt(slide)
                        grip = mu * dn
                        for a in range(d):
                            if slide <= grip:
                                fix[k, a] = vc[a] - new[k, p, a, node]
                            else:
                                fix[k, a] = -dn * normal[k, p, o + a, node] - grip * t[a] / slide
                    for k in range(K):
                        m = sums[k, p, 0, node]
                        ke = 0.0
                        wf = 0.0
                        wg = 0.0
                        for a in range(d):
                            if fix[k, a] == 0.0:
                                continue
                            old = new[k, p, a, node]
                            nw = old + fix[k, a]
                            new[k, p, a, node] = nw
                            if not momentum_only:
                                new[k, p, d + a, node] += fix[k, a]
                                out[p, k, a] += m * fix[k, a]
                                ke += 0.5 * m * (nw * nw - old * old)
                                if m > heavy:
                                    wf += 0.5 * dt * sums[k, p, 1 + d + a, node] * fix[k, a]
                                wg += 0.5 * dt * m * gvec[a] * fix[k, a]
                        out[p, k, 3] += ke - wf - wg
                        out[p, k, 4] += wf
                        out[p, k, 5] += wg
    return out


@kernel
def field_of_rows(gid, body_start, field_of_body, field):
    """Every physical row's field: its body is the seeding block its global id falls in
    (``body_start``: the first global id of every body, then the total)."""
    nb = field_of_body.size
    for i in range(gid.size):
        g = gid[i]
        lo = 0
        hi = nb - 1
        while lo < hi:  # the last body whose first id is <= g
            mid = (lo + hi + 1) // 2
            if body_start[mid] <= g:
                lo = mid
            else:
                hi = mid - 1
        field[i] = field_of_body[lo]


@kernel
def split_by_field(start, order, field, starts, orders):
    """Each field's share of the canonical order, slot by slot: ``starts[k]`` (slots + 1) and
    ``orders[k]`` (its first ``starts[k, -1]`` entries) visit field ``k``'s rows in the same
    canonical order as ``order`` (None: the rows lie in canonical order)."""
    K = starts.shape[0]
    n = np.zeros(K, np.int64)
    for p in range(start.size - 1):
        for k in range(K):
            starts[k, p] = n[k]
        for kk in range(start[p], start[p + 1]):
            i = kk if order is None else np.int64(order[kk])
            k = field[i]
            orders[k, n[k]] = i
            n[k] += 1
    for k in range(K):
        starts[k, start.size - 1] = n[k]
