"""Evaluate one particle's (node, weight, gradient) entries outside the solver, for property tests."""
import numpy as np

from decomposition import PatchLayout
from parmpm.core.records import kernel_lcr
from parmpm.shapes import CPDI, KINDS
from parmpm.shapes.cpdi2 import SCRATCH_SHAPE
from parmpm.shapes.support import domain_matrix, particle_support

#: the empty ``corners`` field of a run without cpdi2, per dimension
NO_CORNERS = {d: np.zeros((0, 1 << d, d)) for d in (1, 2, 3)}


def entries(method, d, x, F=None, lh0=None, r0=None, lcr=None, h=None, cells=12, ghost=3, jit=True):
    """Global node coordinates (n, d), weights (n,), gradients (n, d) of a particle at ``x`` in a
    single-patch grid of ``cells`` cells of size ``h`` per axis (origin 0)."""
    lay = PatchLayout((cells,) * d, (cells,) * d, ghost)
    return _entries(method, d, x, F, lh0, r0, lcr, h, lay, lay.local_base()[0], jit)


def entries_in_patch(method, d, x, layout, coords, F=None, lh0=None, r0=None, lcr=None, h=None,
                     jit=True):
    """As :func:`entries`, but the local (ghost-inclusive) box is that of the patch at ``coords``
    of ``layout``: ``None`` means the particle touches a node outside the grid or beyond that
    patch's ghost layer."""
    coords3 = tuple(int(c) for c in coords) + (0,) * (3 - len(coords))
    return _entries(method, d, x, F, lh0, r0, lcr, h, layout,
                    layout.local_base()[layout.patch_id(coords3)], jit)


def _entries(method, d, x, F, lh0, r0, lcr, h, lay, base, jit):
    h = np.ones(d) if h is None else np.asarray(h, float)
    F = np.eye(d) if F is None else np.asarray(F, float)
    lh0 = 0.25 * h if lh0 is None else np.asarray(lh0, float)
    r0 = np.diag(lh0) if r0 is None else np.asarray(r0, float)
    nloc, nglob = lay.local_nodes3, lay.global_nodes3
    inv_h = np.concatenate([1.0 / h, np.ones(3 - d)])
    xi = np.zeros(3)
    xi[:d] = np.asarray(x, float) / h
    R, C = np.zeros((3, 3)), np.zeros((3, 3))
    M = int(nloc.max())
    K = max(64, int(np.prod(nloc[:d])))
    nk = np.zeros(3, np.int64)
    jk, wk, dwk = np.zeros((3, M), np.int64), np.zeros((3, M)), np.zeros((3, M))
    idx, w, g = np.zeros(K, np.int64), np.zeros(K), np.zeros((K, 3))
    dm = domain_matrix if jit else domain_matrix.py_func
    ps = particle_support if jit else particle_support.py_func
    dm(d, method, kernel_lcr(lcr), F, r0, R)
    n = ps(KINDS[method], d, xi, F, lh0, R, C, base, nloc, nglob, inv_h, nk, jk, wk, dwk, idx, w, g,
           NO_CORNERS[d], 0, kernel_lcr(lcr), np.zeros(SCRATCH_SHAPE))
    if n < 0:
        return None
    loc = idx[:n]
    i0 = loc % nloc[0]
    i1 = (loc // nloc[0]) % nloc[1]
    i2 = loc // (nloc[0] * nloc[1])
    nodes = (np.stack([i0, i1, i2], axis=1) + base)[:, :d] * h
    return nodes, w[:n].copy(), g[:n, :d].copy(), R[:d, :d].copy()


def domain(d, F, r0, lcr=None, jit=True):
    """The CPDI domain ``R' `` (d, d) that ``domain_matrix`` builds from ``F`` and ``R0`` (capped at
    ``lcr``; None: no domain scaling), without evaluating any weights."""
    R = np.zeros((3, 3))
    dm = domain_matrix if jit else domain_matrix.py_func
    dm(d, CPDI, kernel_lcr(lcr), np.asarray(F, float), np.asarray(r0, float), R)
    return R[:d, :d].copy()
