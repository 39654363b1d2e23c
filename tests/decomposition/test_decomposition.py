"""The patch decomposition without MPM physics.

* ownership: the owned boxes partition the global node box ``[0, cells]`` (inclusive);
* halo round trip: ``accumulate`` then ``fill`` leaves the global sum on every copy of a node;
* a fixed summation order (bit-for-bit repeatable, independent of how patches are numbered/stored);
* the ghost widths that :mod:`parmpm.shapes` claims are sufficient, and tight.
"""
import math

import numpy as np
import pytest
from shape_harness import entries_in_patch

from decomposition import HaloPlan, PatchLayout, accumulate, accumulate_max, fill
from decomposition import halo as _halo
from parmpm.shapes import CPDI, INTERPOLATORS, MPM, UGIMP

# (cells, patch_size, ghost): partial last patches, ghost 0/1/2, ghost > patch size, one patch
LAYOUTS = [
    ((10,), (3,), 0), ((10,), (3,), 1), ((10,), (3,), 2), ((7,), (2,), 3), ((9,), (4,), 2),
    ((5,), (5,), 1), ((1,), (1,), 2),
    ((7, 5), (3, 2), 1), ((6, 4), (2, 2), 3), ((4, 7), (4, 3), 2), ((5, 3), (2, 2), 0),
    ((5, 5), (5, 5), 1),
    ((5, 4, 3), (2, 3, 2), 1), ((4, 4, 4), (2, 2, 2), 3), ((5, 3, 4), (3, 2, 2), 2),
    ((5, 3, 4), (2, 2, 3), 0), ((3, 3, 3), (3, 3, 3), 0),
]
LAYOUT_IDS = [f"c{'x'.join(map(str, c))}-p{'x'.join(map(str, p))}-g{g}" for c, p, g in LAYOUTS]

# STYLE item 4: the halo kernels compiled and through their pure-Python bodies
def _py_owner(mode):
    """One-rank accumulate (``mode`` 1), its maximum (2) or fill (0) through the kernel's
    pure-Python body."""
    def run(plan, f):
        ob, obuf, _, _ = plan._buffers(f.shape[2])
        _halo._owner_rows.py_func(f, plan.own_rows, plan.local_nodes3, obuf, ob,
                                  plan.own_seg_nodes, 0, mode)
    return run


KERNELS = {
    "jit": (lambda plan, f: accumulate(plan, f), lambda plan, f: fill(plan, f)),
    "py": (_py_owner(1), _py_owner(0)),
}


def _layout(case):
    cells, psize, ghost = case
    return PatchLayout(cells, psize, ghost)


def _global_index(lay):
    """(n_patches, n_local_nodes) flat global node index of every local node (-1: outside the
    grid), and the matching inside-the-grid mask."""
    L, G = lay.local_nodes3, lay.global_nodes3
    loc = np.arange(lay.n_local_nodes)
    i3 = np.stack([loc % L[0], (loc // L[0]) % L[1], loc // (L[0] * L[1])], axis=1)
    g3 = lay.local_base()[:, None, :] + i3[None, :, :]  # (patches, nodes, 3)
    inside = np.all((g3 >= 0) & (g3 < G), axis=2)
    flat = g3[..., 0] + G[0] * (g3[..., 1] + G[1] * g3[..., 2])
    return np.where(inside, flat, -1), inside


def _partials(lay, rng, k=2):
    """Random per-patch partial sums, zero at local nodes outside the global grid."""
    _, inside = _global_index(lay)
    f = rng.standard_normal((lay.n_patches, lay.n_local_nodes, k))
    f[~inside] = 0.0
    return f


# --- ownership ----------------------------------------------------------------------------------

@pytest.mark.parametrize("case", LAYOUTS, ids=LAYOUT_IDS)
def test_every_node_has_one_owner(case):
    lay = _layout(case)
    count = np.zeros(lay.global_nodes3[::-1], dtype=int)  # indexed [i2, i1, i0]
    for c in lay.patch_coords():
        lo, hi = lay.owned_box(c)
        assert np.all(lo < hi)
        count[lo[2]:hi[2], lo[1]:hi[1], lo[0]:hi[0]] += 1
        llo, lhi = lay.local_box(c)  # the owned box is held locally
        assert np.all(llo <= lo) and np.all(hi <= lhi)
    assert np.all(count == 1), f"nodes with {set(count.ravel())} owners"
    assert count.size == np.prod(np.array(lay.cells) + 1)


# --- halo round trip ----------------------------------------------------------------------------

@pytest.mark.parametrize("kernels", ["jit", "py"])
@pytest.mark.parametrize("case", LAYOUTS, ids=LAYOUT_IDS)
def test_accumulate_fill_gives_global_sum_on_every_copy(case, kernels):
    lay = _layout(case)
    acc, fil = KERNELS[kernels]
    rng = np.random.default_rng([2, LAYOUTS.index(case)])
    f = _partials(lay, rng)
    gidx, inside = _global_index(lay)
    n_glob = int(np.prod(lay.global_nodes3))
    expected = np.zeros((n_glob, f.shape[2]))
    magnitude = np.zeros((n_glob, f.shape[2]))
    np.add.at(expected, gidx[inside], f[inside])  # scatter every local copy
    np.add.at(magnitude, gidx[inside], np.abs(f[inside]))

    plan = HaloPlan(lay)
    acc(plan, f)
    fil(plan, f)

    assert np.all(f[~inside] == 0.0)  # nodes outside the grid are never written
    got = f[inside]
    # relative to the node's Σ|partial| (the scale of its round-off)
    np.testing.assert_array_less(np.abs(got - expected[gidx[inside]]),
                                 1e-12 * magnitude[gidx[inside]] + 1e-300)
    # all copies of one node are bit-identical (the owner's value was copied to every ghost)
    first = np.full((n_glob, f.shape[2]), np.nan)
    first[gidx[inside][::-1]] = got[::-1]  # some copy of each node
    np.testing.assert_array_equal(got, first[gidx[inside]])
    # and every global node has a copy
    assert np.all(np.isin(np.arange(n_glob), gidx[inside]))


@pytest.mark.parametrize("kernels", ["jit", "py"])
@pytest.mark.parametrize("case", LAYOUTS, ids=LAYOUT_IDS)
def test_accumulate_max_gives_every_owner_the_largest_copy(case, kernels):
    """accumulate_max (contact's per-node extremes, :mod:`parmpm.grid.contact`): every owned
    node ends with the largest value any local copy of it held, computed here by numpy's
    scatter-maximum over the global node index."""
    lay = _layout(case)
    rng = np.random.default_rng([4, LAYOUTS.index(case)])
    f = _partials(lay, rng)
    gidx, inside = _global_index(lay)
    n_glob = int(np.prod(lay.global_nodes3))
    expected = np.full((n_glob, f.shape[2]), -np.inf)
    np.maximum.at(expected, gidx[inside], f[inside])
    plan = HaloPlan(lay)
    if kernels == "jit":
        accumulate_max(plan, f)
    else:
        _py_owner(2)(plan, f)
    fill(plan, f)
    np.testing.assert_array_equal(f[inside], expected[gidx[inside]])


def _reference_accumulate(lay, f):
    """Pure-Python statement of the summation order: each owned node's total is
    ``own + Σ_{neighbour offsets, in layout.neighbour_offsets() order} neighbour's copy``."""
    gidx, inside = _global_index(lay)
    out = f.copy()
    coords = lay.patch_coords()
    nppa = lay.patches_per_axis
    for p, c in enumerate(coords):
        lo, hi = lay.owned_box(c)
        for ln in range(lay.n_local_nodes):
            g = gidx[p, ln]
            if g < 0:
                continue
            g3 = np.array([g % lay.global_nodes3[0], (g // lay.global_nodes3[0]) % lay.global_nodes3[1],
                           g // (lay.global_nodes3[0] * lay.global_nodes3[1])])
            if not (np.all(lo <= g3) and np.all(g3 < hi)):
                continue
            total = f[p, ln].copy()
            for off in lay.neighbour_offsets():
                qc = c + np.array(off)
                if np.any(qc < 0) or np.any(qc >= nppa):
                    continue
                q = lay.patch_id(qc)
                hits = np.flatnonzero(gidx[q] == g)
                assert len(hits) <= 1
                if len(hits):
                    total = total + f[q, hits[0]]
            out[p, ln] = total
    return out


@pytest.mark.parametrize("kernels", ["jit", "py"])
@pytest.mark.parametrize("case", LAYOUTS, ids=LAYOUT_IDS)
def test_summation_order_is_fixed(case, kernels):
    """Floating-point addition is not associative: ``(a + b) + c`` and ``a + (b + c)`` can differ
    in the last bit. Rank-count independence (the same particle state bit for bit on
    1..4 ranks) therefore needs every node's ghost contributions added in one fixed order — own
    value first, then neighbours by offset — whichever rank hosts which patch and however the
    patches are numbered in the field arrays."""
    lay = _layout(case)
    acc, _ = KERNELS[kernels]
    rng = np.random.default_rng([3, LAYOUTS.index(case)])
    # values of very different magnitudes make the order visible in the last bits
    f = _partials(lay, rng) * np.exp(rng.uniform(-20, 20, (lay.n_patches, lay.n_local_nodes, 1)))
    plan = HaloPlan(lay)
    a, b = f.copy(), f.copy()
    acc(plan, a)
    acc(plan, b)
    np.testing.assert_array_equal(a, b)  # repeatable
    np.testing.assert_array_equal(a, _reference_accumulate(lay, f))  # in the documented order
    # the slot order is canonical (ascending id) whatever order the ids are given in
    perm = rng.permutation(lay.n_patches)
    c = f.copy()
    acc(HaloPlan(lay, patch_ids=perm), c)
    np.testing.assert_array_equal(c, a)


@pytest.mark.parametrize("case", LAYOUTS, ids=LAYOUT_IDS)
def test_ghost_nodes_per_exchange(case):
    lay = _layout(case)
    n = HaloPlan(lay).ghost_nodes_per_exchange
    if lay.n_patches > 1:
        assert n > 0
    else:
        assert n == 0


# --- ghost widths claimed by the interpolator registry ------------------------------------------

P = 4  # interior patch of P cells per axis in a 3P grid: its ghost layer stays inside the grid
H = np.array([1.0, 0.7, 1.3])


def _patch_positions(rng, d, h, n):
    """Particle centres in the interior patch's cells ``[P, 2P)`` (grid units) per axis: uniform,
    and right at the patch's low edge and just below its high edge."""
    choice = rng.integers(0, 3, (n, d))
    xi = rng.uniform(P, 2 * P, (n, d))
    xi[choice == 1] = P
    xi[choice == 2] = 2 * P
    x = xi * h
    hi = choice == 2
    x[hi] = np.nextafter(x[hi], 0.0)
    for _ in range(8):  # nudge until the harness's x/h lies in the patch's cells
        low = np.floor(x / h) < P
        high = np.floor(x / h) >= 2 * P
        if not (low.any() or high.any()):
            break
        x[low] = np.nextafter(x[low], np.inf)
        x[high] = np.nextafter(x[high], 0.0)
    cell = np.floor(x / h)
    assert np.all((P <= cell) & (cell < 2 * P))
    return x


def _stretched_F(rng, d):
    """Random strong deformation (stretch up to 6 along a random direction, shear, rotation)."""
    n = rng.standard_normal(d)
    n /= np.linalg.norm(n)
    F = np.eye(d) + (rng.uniform(1.0, 6.0) - 1.0) * np.outer(n, n)
    F = F @ (np.eye(d) + np.triu(0.8 * rng.standard_normal((d, d)), 1))
    Q, _ = np.linalg.qr(rng.standard_normal((d, d)))
    return Q @ F * np.sign(np.linalg.det(Q))


def _ghost_cases():
    """(interpolator name, lcr as a multiple of min Δx or None, ppc)."""
    yield "mpm", None, 1
    yield "bspline", None, 1
    for ppc in (1, 2, 3):
        yield "ugimp", None, ppc
    for lcr in (2.0, 1.8 / 3, 1.0, 1.5, 3.0):  # "2dx", "1.8dx/3", …
        yield "cpdi", lcr, 1


@pytest.mark.parametrize("jit", [pytest.param(True, id="jit"), pytest.param(False, id="py")])
@pytest.mark.parametrize("d", [1, 2, 3])
@pytest.mark.parametrize("name,lcr_dx,ppc", list(_ghost_cases()))
def test_ghost_width_holds_every_node_and_is_tight(name, lcr_dx, ppc, d, jit):
    interp = INTERPOLATORS[name]
    assert interp.bounded
    h = H[:d].copy()
    lcr = None if lcr_dx is None else lcr_dx * h.min()
    width = interp.ghost_width(lcr, h.min())
    if lcr_dx is not None:
        assert width == max(1, math.ceil(lcr_dx - 1e-9))
    rng = np.random.default_rng([8, d, len(name), int(ppc), int(1000 * (lcr_dx or 0)), int(jit)])
    n = 400 if jit else 40
    x = _patch_positions(rng, d, h, n)
    # for cpdi, lh0 = Δx/2 and strong stretch so that many domains are capped at lcr
    F = [_stretched_F(rng, d) if interp.code == CPDI else np.eye(d) for _ in range(n)]
    lh0 = h / (2.0 * ppc)
    coords = (1,) * d

    def reach_ok(ghost):
        lay = PatchLayout((3 * P,) * d, (P,) * d, ghost)
        return [entries_in_patch(interp.code, d, x[s], lay, coords, F=F[s], lh0=lh0, lcr=lcr, h=h,
                                 jit=jit) is not None for s in range(n)]

    ok = reach_ok(width)
    assert all(ok), f"{name}: particle at {x[ok.index(False)]} reaches past {width} ghost cells"
    if width > 0:
        assert not all(reach_ok(width - 1)), f"{name}: ghost width {width} is not tight"
    else:
        assert interp.code == MPM


def test_unbounded_interpolators_default_ghost():
    for name in ("cpgimp",):
        assert not INTERPOLATORS[name].bounded
        assert INTERPOLATORS[name].ghost_width(None, 0.5) == 2
    assert INTERPOLATORS["cpdi"].ghost_width(None, 0.5) == 2  # unscaled cpdi
    assert INTERPOLATORS["ugimp"].code == UGIMP


# --- sparse patch set and partition --------------------------------------------------------------
from decomposition.partition import (  # noqa: E402
    active_patches,
    assign,
    imbalance,
    morton_order,
    split_contiguous,
)


def _box_patches(lay, lo_cell, hi_cell):
    """Patches holding any cell of the cell box [lo_cell, hi_cell)."""
    axes = [np.arange(lo, hi) for lo, hi in zip(lo_cell, hi_cell)]
    cells = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, lay.dim)
    c3 = np.zeros((cells.shape[0], 3), np.int64)
    c3[:, :lay.dim] = cells
    return np.unique(lay.patch_id(c3 // lay.psize3))


@pytest.mark.parametrize("psize,expected", [(4, 20), (2, 80)])
def test_sparse_set_for_the_hanging_bar(psize, expected):
    """The 2D hanging bar (20 × 32 cells of 0.1 m; the bar fills cells x 5..14, y 20..29) with
    ghost 2: only the bar's patches and those within halo reach of them exist (one patch when
    the patch is 4 cells, two when it is 2 cells, since a 2-cell ghost layer then spans a whole
    neighbour patch): 20 of 40 and 80 of 160."""
    lay = PatchLayout((20, 32), (psize, psize), 2)
    ids = active_patches(lay, _box_patches(lay, (5, 20), (15, 30)))
    assert ids.size == expected and lay.n_patches == {4: 40, 2: 160}[psize]
    assert np.all(np.diff(ids) > 0)


def test_sparse_set_covers_every_node_a_patch_touches():
    """Every patch that owns a node inside an occupied patch's ghost-inclusive box exists."""
    lay = PatchLayout((30, 20, 10), (3, 4, 2), 2)
    rng = np.random.default_rng(4)
    occ = rng.choice(lay.n_patches, 7, replace=False)
    ids = set(active_patches(lay, occ).tolist())
    coords = lay.patch_coords()
    for p in occ:
        lo, hi = lay.local_box(coords[p])
        lo, hi = np.maximum(lo, 0), np.minimum(hi, lay.global_nodes3)
        for q, c in enumerate(coords):
            olo, ohi = lay.owned_box(c)
            if np.all(np.maximum(lo, olo) < np.minimum(hi, ohi)):
                assert q in ids


def test_morton_partition_is_contiguous_and_balanced():
    lay = PatchLayout((64, 64), (4, 4), 2)
    rng = np.random.default_rng(2)
    ids = np.arange(lay.n_patches)
    counts = rng.integers(50, 150, ids.size)
    for n in (1, 2, 3, 4, 7):
        owner = assign(lay, ids, counts, n)
        along = owner[np.searchsorted(ids, morton_order(lay, ids))]
        assert np.all(np.diff(along) >= 0)  # contiguous pieces of the curve
        loads = np.bincount(owner, weights=counts + 1, minlength=n)
        assert imbalance(loads) < 0.02
    assert np.array_equal(split_contiguous(np.ones(4), 2), [0, 0, 1, 1])
    assert np.array_equal(split_contiguous(np.zeros(3), 3), [0, 1, 2])


@pytest.mark.parametrize("case", LAYOUTS, ids=LAYOUT_IDS)
def test_among_the_holding_slots_gives_their_copies_the_whole_plans_bits(case):
    """``HaloPlan.among(holding)`` (contact's per-field exchanges): partial sums only in the
    slots ``holding`` marks (zeros elsewhere, as a field's P2G leaves them), accumulated and
    filled over the kept pairs, give every copy in those slots the bits of the whole plan's;
    a slot the sub-plan does not mark ``reached`` gets nothing from the whole plan either."""
    lay = _layout(case)
    rng = np.random.default_rng([7, LAYOUTS.index(case)])
    for trial in range(4):
        holding = rng.random(lay.n_patches) < (0.2, 0.5, 0.8, 1.0)[trial]
        f = _partials(lay, rng)
        f[~holding] = 0.0
        whole, part = f.copy(), f.copy()
        plan = HaloPlan(lay)
        sub = plan.among(holding)
        assert plan.among(holding) is sub  # kept for the next step
        accumulate(plan, whole)
        unreached = ~sub.reached
        assert np.all(whole[unreached] == 0.0)
        fill(plan, whole)
        accumulate(sub, part)
        fill(sub, part)
        np.testing.assert_array_equal(part[holding], whole[holding])
        assert sub.own_rows.shape[0] <= plan.own_rows.shape[0]
