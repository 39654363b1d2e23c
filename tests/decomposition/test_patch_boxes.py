"""Patch-box arithmetic (:mod:`decomposition.boxes`) and its compiled form for the kernels
(:mod:`parmpm.grid.patch_index`): owned box, ghost base, cell → patch, point → patch; the compiled
helpers agree with the plain functions, inline into their callers and cache (STYLE items 2, 4)."""
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from decomposition import PatchLayout, boxes
from parmpm.particles.locate import locate_patches
from parmpm.core.records import Locate
from parmpm.grid.patch_index import (next_patch_2d, next_patch_3d, patch_id1, patch_id2, patch_id3,
                                 patch_index, patches_holding_node)

ROOT = Path(__file__).resolve().parents[2]


# --- boxes --------------------------------------------------------------------------------------

def test_owned_boxes_along_one_axis_and_the_last_patch_takes_the_far_node():
    """10 cells in patches of 3: [0,3) [3,6) [6,9) and the partial last one [9,11)."""
    k = np.arange(4)
    lo, hi = boxes.owned_box(k, 3, 4, 11)
    assert lo.tolist() == [0, 3, 6, 9] and hi.tolist() == [3, 6, 9, 11]
    lo, hi = boxes.owned_box(k, 5, 4, 21)  # 20 cells in 4 whole patches
    assert hi.tolist() == [5, 10, 15, 21]


def test_ghost_base_is_k_P_minus_g():
    assert boxes.ghost_base(np.arange(4), 3, 2).tolist() == [-2, 1, 4, 7]


@pytest.mark.parametrize("cells,psize,ghost", [((10,), (3,), 2), ((7, 5), (3, 2), 1),
                                               ((5, 4, 3), (2, 3, 2), 3)])
def test_padded_axes_are_one_patch_of_one_node_without_ghosts(cells, psize, ghost):
    lay = PatchLayout(cells, psize, ghost)
    coords = lay.patch_coords()
    lo, hi = lay.owned_box(coords)
    base = lay.local_base(coords)
    pad = slice(lay.dim, 3)
    assert np.all(lo[:, pad] == 0) and np.all(hi[:, pad] == 1) and np.all(base[:, pad] == 0)
    assert np.all(base[:, :lay.dim] == coords[:, :lay.dim] * lay.psize3[:lay.dim] - ghost)
    # flat ids run axis 0 fastest and invert patch_coords
    assert lay.patch_id(coords).tolist() == list(range(lay.n_patches))


@pytest.mark.parametrize("cells,psize,ghost", [(10, 3, 0), (10, 3, 2), (7, 2, 3), (9, 4, 1),
                                               (5, 5, 1), (1, 1, 0)])
def test_patches_holding_a_node_are_those_whose_local_box_holds_it(cells, psize, ghost):
    lay = PatchLayout((cells,), (psize,), ghost)
    lo, hi = lay.local_box(lay.patch_coords())
    n = int(lay.patches_per_axis[0])
    for i in range(cells + 1):
        holders = np.flatnonzero((lo[:, 0] <= i) & (i < hi[:, 0]))
        want = (int(holders[0]), int(holders[-1]))
        assert np.array_equal(holders, np.arange(want[0], want[1] + 1))
        assert boxes.patches_holding_node(i, psize, ghost, n) == want
        assert patches_holding_node(i, psize, ghost, n) == want
    assert boxes.patches_holding_node(0, 1, 0, 1) == (0, 0)  # a padded axis


def test_patch_of_cell_is_floor_division():
    for p in range(1, 18):
        c = np.arange(0, 5000)
        got = [boxes.patch_of_cell(int(ci), p, 1.0 / p) for ci in c]
        assert got == (c // p).tolist()


def test_patch_of_coordinate_on_edges_and_outside():
    """A point on a patch edge belongs to the patch above; the far face, negatives and NaN are
    outside; -0.0 is inside."""
    def f(u):
        return boxes.patch_of_coordinate(u, 10, 3, 1.0 / 3)

    assert [f(float(u)) for u in (0, 3, 6, 9)] == [0, 1, 2, 3]
    assert [f(np.nextafter(float(u), -1.0)) for u in (3, 6, 9)] == [0, 1, 2]
    assert f(np.nextafter(10.0, 0.0)) == 3 and f(-0.0) == 0
    assert f(10.0) == f(-1e-300) == f(np.nan) == f(np.inf) == -1


LOC_CASES = [((10,), (3,)), ((7, 5), (3, 2)), ((5, 4, 3), (2, 3, 2)), ((12, 9, 8), (4, 4, 3))]


def _points(lay, rng, n=400):
    """Points inside and just outside the grid (origin -1, cell size 0.25), some on edges."""
    h, o = 0.25, -1.0
    u = rng.uniform(-0.5, 1.0, (n, lay.dim)) * lay.cells3[:lay.dim] * 1.1
    u[: n // 4] = rng.integers(0, lay.cells3[:lay.dim] + 1, (n // 4, lay.dim))  # nodes
    return o + u * h, np.full(3, o), np.full(3, 1.0 / h)


def _reference_ids(lay, x, origin, inv_h):
    """Flat patch id by floor division, -1 outside."""
    u = (x - origin[:lay.dim]) * inv_h[:lay.dim]
    inside = np.all((u >= 0) & (u < lay.cells3[:lay.dim]), axis=1)
    c3 = np.zeros((x.shape[0], 3), np.int64)
    c3[:, :lay.dim] = np.where(inside[:, None], np.floor(u), 0)
    return np.where(inside, lay.patch_id(c3 // lay.psize3), -1)


def _point_ids(fn, x, origin, inv_h, loc, inv_ps):
    return np.array([fn(*xi, origin, inv_h, loc, inv_ps) for xi in x])


POINT_FNS = {1: patch_id1, 2: patch_id2, 3: patch_id3}


@pytest.mark.parametrize("cells,psize", LOC_CASES)
def test_patch_of_point_matches_floor_division_compiled_and_plain(cells, psize):
    lay = PatchLayout(cells, psize, 2)
    x, origin, inv_h = _points(lay, np.random.default_rng(len(cells)))
    loc, inv_ps = lay.locator()
    ref = _reference_ids(lay, x, origin, inv_h)
    assert np.any(ref < 0) and np.any(ref >= 0)
    fn = POINT_FNS[lay.dim]
    assert fn.py_func is getattr(boxes, f"patch_of_point_{lay.dim}d")
    np.testing.assert_array_equal(_point_ids(fn.py_func, x, origin, inv_h, loc, inv_ps), ref)
    np.testing.assert_array_equal(_point_ids(fn, x, origin, inv_h, loc, inv_ps), ref)
    for k in range(lay.dim):  # the per-axis helper, compiled and plain
        u = (x[:, k] - origin[k]) * inv_h[k]
        args = (loc[0, k], loc[1, k], inv_ps[k])
        assert [patch_index(ui, *args) for ui in u] == [patch_index.py_func(ui, *args) for ui in u]
    # the particle locator: the same ids; outside points keep their current patch
    current = np.full(x.shape[0], 7, np.int64)
    out = np.empty_like(current)
    first, moved = locate_patches(lay.dim, x, origin, inv_h, lay.cells3, lay.psize3,
                                  lay.patches_per_axis, current, out)
    np.testing.assert_array_equal(out, np.where(ref < 0, 7, ref))
    assert first == np.flatnonzero(ref < 0)[0] and moved == np.sum((ref >= 0) & (ref != 7))


@pytest.mark.parametrize("cells,psize", LOC_CASES[1:])
def test_next_patch_answers_patch_id_from_every_patch(cells, psize):
    """G2P's stay-in-patch test (:func:`next_patch_2d`, ``_3d``) gives :func:`patch_id2`'s answer
    whichever patch the particle was in: points on patch edges, one ulp below them, on the far
    face, outside, NaN."""
    lay = PatchLayout(cells, psize, 2)
    x, origin, inv_h = _points(lay, np.random.default_rng(5), n=3000)
    u = (x - origin[:lay.dim]) * inv_h[:lay.dim]
    edges = np.nextafter(u, -np.inf)  # just below whatever edge a node point sits on
    x = np.concatenate([x, origin[:lay.dim] + edges / inv_h[:lay.dim], np.full((2, lay.dim), np.nan)])
    loc, inv_ps = lay.locator()
    ref = _reference_ids(lay, x, origin, inv_h)
    coords = lay.patch_coords()
    lo, hi = lay.patch_cells(coords)
    inside = np.stack([lo, hi], axis=1).astype(np.float64)
    locate = Locate(loc, inv_ps, np.arange(lay.n_patches), np.zeros(0, np.int64), inside)
    fn = next_patch_2d if lay.dim == 2 else next_patch_3d
    for p in range(lay.n_patches):
        got = [fn(*xi, origin, inv_h, locate, p, p) for xi in x]
        np.testing.assert_array_equal(got, ref)
    assert np.unique(ref[ref >= 0]).size == lay.n_patches  # each patch's fast path answers


def test_locator_rows():
    lay = PatchLayout((7, 5), (3, 2), 1)
    loc, inv_ps = lay.locator()
    assert loc.tolist() == [[7, 5, 0], [3, 2, 1], [3, 3, 1]]
    assert inv_ps.tolist() == [1 / 3, 1 / 2, 1.0]


# --- compiled helpers inline and cache -------------------------------------------------------------

CALLER = '''
import numpy as np
from parmpm.core.jit import kernel
from parmpm.grid.patch_index import patch_id2, patch_id3


@kernel
def ids(x, origin, inv_h, loc, inv_ps):
    out = np.empty(x.shape[0], np.int64)
    for i in range(x.shape[0]):
        if x.shape[1] == 2:
            out[i] = patch_id2(x[i, 0], x[i, 1], origin, inv_h, loc, inv_ps)
        else:
            out[i] = patch_id3(x[i, 0], x[i, 1], x[i, 2], origin, inv_h, loc, inv_ps)
    return out
'''

RUN = '''
import numpy as np
from decomposition import PatchLayout
from parmpm.grid.patch_index import patch_id2, patch_id3
from caller import ids
lay = PatchLayout((12, 9), (4, 4), 2)
loc, inv_ps = lay.locator()
x = np.random.default_rng(0).uniform(-0.5, 3.5, (50, 2))
got = ids(x, np.zeros(3), np.full(3, 4.0), loc, inv_ps)
lines = "".join(ids.inspect_llvm().values()).splitlines()
calls = any(" call " in s and "patch_of" in s for s in lines)  # a call left to either helper
print(ids.stats.cache_hits.total(), len(patch_id2.signatures) + len(patch_id3.signatures),
      calls, got.sum())
'''


def test_compiled_helpers_inline_into_a_caller_that_caches(tmp_path):
    """A ``@kernel`` calling patch_id2/3 leaves no call to them in its optimised code (LLVM
    inlined them), and a second process loads it from the on-disk cache."""
    (tmp_path / "caller.py").write_text(textwrap.dedent(CALLER))
    env = dict(os.environ, PYTHONPATH=f"{tmp_path}{os.pathsep}{ROOT}",
               NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    runs = [subprocess.run([sys.executable, "-c", RUN], cwd=tmp_path, env=env, check=False,
                           capture_output=True, text=True, timeout=300) for _ in range(2)]
    out = []
    for r in runs:
        assert r.returncode == 0, r.stderr[-2000:]
        out.append(r.stdout.split())
    (hits0, compiled0, calls0, sum0), (hits1, *_, sum1) = out
    assert hits0 == "0" and hits1 == "1"
    assert int(compiled0) > 0 and calls0 == "False"  # typed apart, inlined by LLVM
    assert sum0 == sum1
