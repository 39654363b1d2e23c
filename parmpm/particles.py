"""Particle store: structure of arrays, grouped by patch (CSR offsets), global-id order inside a
patch.

Fields use the literature's names: ``x`` position, ``v`` velocity, ``x0`` reference position,
``mass``, ``vol0`` initial volume, ``F`` deformation gradient, ``stress`` (Cauchy), ``r0`` initial
CPDI domain vectors (columns, physical units), ``lh0`` initial GIMP half-widths, ``mat`` material
row, ``damage`` (for damage models), ``rf`` a frozen CPDI domain in the material's unrotated
frame (zeros: not frozen; :mod:`parmpm.shapes.freeze`), ``affine`` the APIC affine velocity
matrix ``C_p = B_p D_p⁻¹`` (Jiang et al. 2015; zeros under FLIP: :mod:`parmpm.affine`),
``corners`` the CPDI2 domain's corners minus the particle's position ``(2^d, d)`` (physical
units, the bit order of :mod:`parmpm.shapes.cpdi2`; moved by the grid in G2P), ``gid`` global id (never changes: it is
how runs on different rank counts and restarts are compared), ``dx`` a scratch displacement for
MUSL.
"""
from __future__ import annotations

import numpy as np
from numba import literal_unroll, literally

from parmpm.jit import DIMS, kernel, loop_kernel
from parmpm.patch_index import patch_id1, patch_id2, patch_id3

FLOAT_FIELDS = ("x", "v", "x0", "mass", "vol0", "F", "stress", "r0", "lh0", "damage", "dx", "rf",
                "affine", "corners")
INT_FIELDS = ("gid", "mat", "patch")
#: fields only the runs that need them carry (elsewhere zero rows, never moved or stored):
#: ``affine`` under APIC, ``corners`` under cpdi2
OPTIONAL_FIELDS = ("affine", "corners")


class Particles:
    """SoA particle arrays of one rank, grouped by local patch slot (``start``: CSR offsets) and
    sorted by global id inside a patch. ``patch`` is the global id of the particle's patch."""

    def __init__(self, dim: int, n: int, optional: tuple[str, ...] = ()):
        unknown = sorted(set(optional) - set(OPTIONAL_FIELDS))
        if unknown:
            raise ValueError(f"not optional particle fields: {unknown} (known: {OPTIONAL_FIELDS})")
        self.dim = dim
        #: the optional fields this store carries (:data:`OPTIONAL_FIELDS`)
        self.optional = tuple(k for k in OPTIONAL_FIELDS if k in optional)
        d = dim
        self.gid = np.zeros(n, np.int64)
        self.mat = np.zeros(n, np.int64)
        self.x, self.v, self.x0, self.lh0, self.dx = (np.zeros((n, d)) for _ in range(5))
        self.mass, self.vol0, self.damage = (np.zeros(n) for _ in range(3))
        self.F = np.zeros((n, d, d))
        self.F[:] = np.eye(d)
        self.stress = np.zeros((n, d, d))
        self.r0 = np.zeros((n, d, d))
        self.rf = np.zeros((n, d, d))
        self.affine = np.zeros((n if "affine" in optional else 0, d, d))
        self.corners = np.zeros((n if "corners" in optional else 0, 1 << d, d))
        self.patch = np.zeros(n, np.int64)
        self.start = np.zeros(1, np.int64)

    @property
    def n(self) -> int:
        return self.gid.size

    def names(self) -> tuple[str, ...]:
        """The fields this store carries: every field but the optional ones it does not."""
        return INT_FIELDS + tuple(k for k in FLOAT_FIELDS
                                  if k not in OPTIONAL_FIELDS or k in self.optional)

    def carry(self, optional: tuple[str, ...]) -> None:
        """Carry exactly the optional fields ``optional`` (a new one starts at zero): a restart
        from a checkpoint that lacks one (an older format) still runs."""
        for k in OPTIONAL_FIELDS:
            a = getattr(self, k)
            rows = self.n if k in optional else 0
            if a.shape[0] != rows:
                setattr(self, k, np.zeros((rows,) + a.shape[1:]))
        self.optional = tuple(k for k in OPTIONAL_FIELDS if k in optional)

    def fields(self) -> dict[str, np.ndarray]:
        return {k: getattr(self, k) for k in self.names()}

    def replace(self, fields: dict[str, np.ndarray]) -> None:
        """Take new arrays for every field (after migration); ``start`` must be rebuilt."""
        for name, arr in fields.items():
            setattr(self, name, arr)

    def permute(self, perm: np.ndarray) -> None:
        """Reorder (or select) every field by ``perm``, one field at a time (so at most one
        field's worth of extra memory is held: the old array goes as soon as it is replaced)."""
        for name in self.names():
            setattr(self, name, np.take(getattr(self, name), perm, axis=0))

    def merge(self, fields: dict[str, np.ndarray], keep: np.ndarray, received: dict | None,
              slot_of: np.ndarray, n_slots: int) -> None:
        """After a migration: the kept rows ``fields[keep]`` and the ``received`` ones, sorted by
        (slot, gid) and written once into fresh arrays (one copy per field, no intermediates).
        ``fields['patch']`` holds the kept rows' new global patch ids; ``fields`` is emptied."""
        k = keep.size
        patch = fields["patch"][keep]
        gid = self.gid[keep]
        if received is not None:
            patch = np.concatenate([patch, received["patch"]])
            gid = np.concatenate([gid, received["gid"]])
        slot = slot_of[patch]
        order = np.argsort(slot * (int(gid.max(initial=0)) + 1) + gid, kind="stable")
        n = order.size
        for name in list(fields):  # popped, so each old array goes once its new one is written
            a = fields.pop(name)
            out = np.empty((n,) + a.shape[1:], a.dtype)
            r = received[name] if received is not None else a[:0]
            w = int(np.prod(a.shape[1:], dtype=np.int64))
            _merge_rows(out.reshape(n, w), a.reshape(a.shape[0], w), r.reshape(r.shape[0], w),
                        keep, order, k)
            setattr(self, name, out)
            del a
        counts = np.bincount(slot, minlength=n_slots)
        self.start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)

    def group_by_patch(self, new_patch: np.ndarray, slot_of: np.ndarray, n_slots: int,
                       force: bool = False) -> bool:
        """Sort by (local slot of the global patch id, gid) and rebuild the CSR offsets; a no-op
        when no particle changed patch (and not ``force``). Returns True if the order changed.
        The order inside a patch depends only on the patch's particles, never on the rank."""
        if (not force and np.array_equal(new_patch, self.patch)
                and self.start.size == n_slots + 1):
            return False
        slot = slot_of[new_patch]
        key = slot * (int(self.gid.max(initial=0)) + 1) + self.gid
        self.patch = new_patch
        order = np.argsort(key, kind="stable")
        self.permute(order)
        counts = np.bincount(slot, minlength=n_slots)
        self.start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        return True


@kernel
def _merge_rows(out, old, new, keep, order, k):
    """``out[i] = (old[keep] ++ new)[order[i]]`` row by row, without building the concatenation."""
    for i in range(order.size):
        j = order[i]
        if j < k:
            s = keep[j]
            for c in range(out.shape[1]):
                out[i, c] = old[s, c]
        else:
            for c in range(out.shape[1]):
                out[i, c] = new[j - k, c]


@kernel
def locate_patches(d, x, origin, inv_h, cells, psize, ppa, current, out):
    """Flat global patch id of each particle's position into ``out``; a particle outside the
    grid keeps ``current``. Returns (the index of the first particle outside the grid or -1, how
    many particles changed patch). The id is :mod:`parmpm.patch_index`'s, the one G2P's
    specialised kernels use; the loop is compiled per dimension without reference counting."""
    loc = np.zeros((3, 3), np.int64)
    inv_ps = np.zeros(3)
    for k in range(d):
        loc[0, k], loc[1, k], loc[2, k] = cells[k], psize[k], ppa[k]
        inv_ps[k] = 1.0 / psize[k]
    result = (-1, 0)
    for dim in literal_unroll(DIMS):
        if dim == d:
            result = _locate_loop(dim, x, origin, inv_h, loc, inv_ps, current, out)
    return result


@loop_kernel
def _locate_loop(dim, x, origin, inv_h, loc, inv_ps, current, out):
    literally(dim)
    first = -1
    moved = 0
    for i in range(x.shape[0]):
        if dim == 1:
            pid = patch_id1(x[i, 0], origin, inv_h, loc, inv_ps)
        elif dim == 2:
            pid = patch_id2(x[i, 0], x[i, 1], origin, inv_h, loc, inv_ps)
        else:
            pid = patch_id3(x[i, 0], x[i, 1], x[i, 2], origin, inv_h, loc, inv_ps)
        if pid < 0:  # outside the grid (NaN too)
            out[i] = current[i]
            if first < 0:
                first = i
        else:
            out[i] = pid
            if pid != current[i]:
                moved += 1
    return first, moved
