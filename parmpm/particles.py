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
        #: the arrays, row ``i`` = physical row ``i`` (see :attr:`rows`)
        self._a: dict[str, np.ndarray] = {}
        #: canonical position -> physical row while the rows are not in canonical order, else None
        self._order: np.ndarray | None = None
        self._identity = np.zeros(0, np.uint64)
        self._leaving = np.zeros(0, np.uint8)  # _regroup's scratch
        self._spare = np.zeros(0, np.uint64)  # the order array _regroup writes next
        #: ``start`` and the order group the rows by their ``patch`` (False after arbitrary
        #: replacements, until :meth:`group_by_patch` or :meth:`merge` regroups them)
        self._grouped = False
        #: rows placed out of canonical order since the last :meth:`compact`
        self.displaced = 0
        a = self._a
        a["gid"] = np.zeros(n, np.int64)
        a["mat"] = np.zeros(n, np.int64)
        for k in ("x", "v", "x0", "lh0", "dx"):
            a[k] = np.zeros((n, d))
        for k in ("mass", "vol0", "damage"):
            a[k] = np.zeros(n)
        a["F"] = np.zeros((n, d, d))
        a["F"][:] = np.eye(d)
        for k in ("stress", "r0", "rf"):
            a[k] = np.zeros((n, d, d))
        a["affine"] = np.zeros((n if "affine" in optional else 0, d, d))
        a["corners"] = np.zeros((n if "corners" in optional else 0, 1 << d, d))
        a["patch"] = np.zeros(n, np.int64)
        self.rows = _Rows(a)
        self.start = np.zeros(1, np.int64)

    @property
    def n(self) -> int:
        return self._a["gid"].size

    # --- canonical order ------------------------------------------------------------------------
    def order(self) -> np.ndarray:
        """Canonical position -> physical row (uint64, what the kernels loop over: patch slot
        ``s`` is ``order[start[s]:start[s + 1]]``); the identity while the rows are compact."""
        if self._order is not None:
            return self._order
        if self._identity.size != self.n:
            self._identity = np.arange(self.n, dtype=np.uint64)
        return self._identity

    def compact(self) -> None:
        """Put the rows into canonical (slot, gid) order (a no-op when they are): every field is
        read through this, so code outside the time step never sees the lazy order."""
        if self._order is None:
            return
        order, self._order = self._order.astype(np.int64), None
        self.displaced = 0
        for name in self.names():
            self._a[name] = np.take(self._a[name], order, axis=0)

    def names(self) -> tuple[str, ...]:
        """The fields this store carries: every field but the optional ones it does not."""
        return INT_FIELDS + tuple(k for k in FLOAT_FIELDS
                                  if k not in OPTIONAL_FIELDS or k in self.optional)

    def carry(self, optional: tuple[str, ...]) -> None:
        """Carry exactly the optional fields ``optional`` (a new one starts at zero): a restart
        from a checkpoint that lacks one (an older format) still runs."""
        self.compact()
        for k in OPTIONAL_FIELDS:
            a = self._a[k]
            rows = self.n if k in optional else 0
            if a.shape[0] != rows:
                self._a[k] = np.zeros((rows,) + a.shape[1:])
        self.optional = tuple(k for k in OPTIONAL_FIELDS if k in optional)

    def fields(self) -> dict[str, np.ndarray]:
        """Every carried field, rows in canonical order."""
        self.compact()
        return self.raw_fields()

    def raw_fields(self) -> dict[str, np.ndarray]:
        """Every carried field as stored (physical rows: the time step's view)."""
        return {k: self._a[k] for k in self.names()}

    def replace(self, fields: dict[str, np.ndarray]) -> None:
        """Take new arrays for every field (after migration); ``start`` must be rebuilt."""
        self._order, self.displaced, self._grouped = None, 0, False
        for name, arr in fields.items():
            self._a[name] = arr

    def permute(self, perm: np.ndarray) -> None:
        """Reorder (or select) every field by ``perm``, one field at a time (so at most one
        field's worth of extra memory is held: the old array goes as soon as it is replaced)."""
        self.compact()
        self._grouped = False
        for name in self.names():
            self._a[name] = np.take(self._a[name], perm, axis=0)

    def merge(self, fields: dict[str, np.ndarray], keep: np.ndarray, received: dict | None,
              slot_of: np.ndarray, n_slots: int) -> None:
        """After a migration: the kept rows ``fields[keep]`` and the ``received`` ones, sorted by
        (slot, gid) and written once into fresh arrays (one copy per field, no intermediates).
        ``fields['patch']`` holds the kept rows' new global patch ids; ``fields`` is emptied."""
        k = keep.size
        patch = fields["patch"][keep]
        gid = self._a["gid"][keep]
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
            self._a[name] = out
            del a
        self._order, self.displaced, self._grouped = None, 0, True
        counts = np.bincount(slot, minlength=n_slots)
        self.start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)

    def group_by_patch(self, new_patch: np.ndarray, slot_of: np.ndarray, n_slots: int,
                       force: bool = False, moved: int = -1) -> bool:
        """Group by (local slot of the global patch id, gid) and rebuild the CSR offsets; a no-op
        when no particle changed patch (and not ``force``). Returns True if the order changed.
        The order inside a patch depends only on the patch's particles, never on the rank.

        Lazily: the new canonical order is an index (:meth:`order`) merged in O(n) from the old
        one and the few particles that changed patch (``moved`` of them, when the caller counted
        them); the rows are copied into that order (:meth:`compact`) only once more than
        :data:`COMPACT_FRACTION` of them sit out of place, or when code outside the step reads
        a field. ``new_patch`` becomes the store's ``patch`` array."""
        a = self._a
        if force or not self._grouped or self.start.size != n_slots + 1:
            force = True
        elif moved == 0 or (moved < 0 and np.array_equal(new_patch, a["patch"])):
            return False
        if force:
            if not (self._grouped and new_patch is a["patch"] and self._reslot(slot_of, n_slots)):
                self.compact()
                slot = slot_of[new_patch]
                key = slot * (int(a["gid"].max(initial=0)) + 1) + a["gid"]
                a["patch"] = new_patch
                self.permute(np.argsort(key, kind="stable"))
                counts = np.bincount(slot, minlength=n_slots)
                self.start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
            self._grouped = True
            return True
        counts = np.diff(self.start)
        out = self._spare if self._spare.size == self.n else np.empty(self.n, np.uint64)
        if self._leaving.size != self.n:
            self._leaving = np.zeros(self.n, np.uint8)
        n_moved = _regroup(self.order(), a["patch"], new_patch, slot_of, a["gid"], self.start,
                           counts, self._leaving, out)
        a["patch"] = new_patch
        # the old order is the next regroup's output buffer (never the array it reads)
        self._spare = self._order if self._order is not None else np.zeros(0, np.uint64)
        self._order = out
        self.start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        self.displaced += n_moved
        if self.displaced > COMPACT_FRACTION * self.n:
            self.compact()
        return True

    def _reslot(self, slot_of: np.ndarray, n_slots: int) -> bool:
        """The patch set changed but every particle's patch is still here: the patches' runs of
        the canonical order move to their new slots (an index copy, no field is touched).
        False when some particle's patch is no longer local (then a full sort is needed)."""
        old = self.start
        sizes = np.diff(old)
        full = np.flatnonzero(sizes)
        first = self.order()[old[full]].astype(np.int64)
        to = slot_of[self._a["patch"][first]] if full.size else np.zeros(0, np.int64)
        if np.any(to < 0) or np.any(to >= n_slots):
            return False
        counts = np.zeros(n_slots, np.int64)
        counts[to] = sizes[full]
        start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        out = np.empty(self.n, np.uint64)
        _move_runs(self.order(), old[full], sizes[full], start[to], out)
        self._order, self.start = out, start
        return True


#: the share of rows out of canonical place at which :meth:`Particles.group_by_patch` copies
#: every field into canonical order (a gather of misplaced rows costs cache misses every pass;
#: the copy costs a pass over all the fields)
COMPACT_FRACTION = 0.25


class _Rows:
    """Attribute access to a store's arrays as stored (physical rows, no compaction): the view
    the time step works on, where a particle index is a physical row."""

    __slots__ = ("_a",)

    def __init__(self, arrays: dict):
        self._a = arrays

    def __getattr__(self, name: str) -> np.ndarray:
        try:
            return self._a[name]
        except KeyError:
            raise AttributeError(name) from None


def _field(name: str) -> property:
    def get(self):
        if self._order is not None:
            self.compact()
        return self._a[name]

    def put(self, value):
        if self._order is not None:
            self.compact()
        if name == "patch":
            self._grouped = False
        self._a[name] = value
    return property(get, put, doc=f"``{name}``, rows in canonical order")


for _name in INT_FIELDS + FLOAT_FIELDS:
    setattr(Particles, _name, _field(_name))


@kernel
def _regroup(order, patch, new, slot_of, gid, start, counts, leaving, out):
    """The canonical order after some particles changed patch: ``out`` merges, slot by slot,
    the old order's particles that stayed (still in gid order) with the ones that arrived
    (sorted by (slot, gid)); ``counts`` (per slot) is updated in place. ``leaving``: a zeroed
    byte per row (left zeroed). Returns how many moved. Two passes: the movers are found in
    row order (sequential reads), the merge reads a stayer's gid only where arrivals wait."""
    n = order.size
    rows = np.empty(n, np.int64)
    m = 0
    top = 0
    for i in range(n):
        if new[i] != patch[i]:
            rows[m] = i
            leaving[i] = 1
            counts[slot_of[patch[i]]] -= 1
            counts[slot_of[new[i]]] += 1
            top = max(top, gid[i])
            m += 1
    key = np.empty(m, np.int64)
    for j in range(m):
        key[j] = slot_of[new[rows[j]]] * (top + 1) + gid[rows[j]]
    srt = np.argsort(key)
    b = 0
    pos = 0
    for s in range(start.size - 1):
        k = start[s]
        end = start[s + 1]
        # arrivals into slot s: srt[b:b_end]
        b_end = b
        while b_end < m and slot_of[new[rows[srt[b_end]]]] == s:
            b_end += 1
        while b < b_end:
            g = gid[rows[srt[b]]]
            while k < end:  # stayers before the next arrival
                i = order[k]
                if leaving[i] == 0:
                    if gid[i] > g:
                        break
                    out[pos] = i
                    pos += 1
                k += 1
            out[pos] = rows[srt[b]]
            pos += 1
            b += 1
        while k < end:  # the rest of the slot's stayers: no gid needed
            i = order[k]
            if leaving[i] == 0:
                out[pos] = i
                pos += 1
            k += 1
    for j in range(m):
        leaving[rows[j]] = 0
    return m


@kernel
def _move_runs(order, src, size, dst, out):
    """``out[dst[r]:dst[r] + size[r]] = order[src[r]:src[r] + size[r]]`` for every run ``r``."""
    for r in range(src.size):
        for k in range(size[r]):
            out[dst[r] + k] = order[src[r] + k]


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


def locate_patches(d, x, origin, inv_h, cells, psize, ppa, current, out, order=None):
    """Flat global patch id of each particle's position into ``out``; a particle outside the
    grid keeps ``current``. Returns (the row of the first particle outside the grid, in
    ``order`` (:meth:`Particles.order`), or -1; how many particles changed patch). The id is :mod:`parmpm.patch_index`'s, the one G2P's
    specialised kernels use; the loop is compiled per dimension without reference counting."""
    if order is None:
        order = np.arange(x.shape[0], dtype=np.uint64)
    return _locate_patches(d, x, origin, inv_h, cells, psize, ppa, current, out, order)


@kernel
def _locate_patches(d, x, origin, inv_h, cells, psize, ppa, current, out, order):
    loc = np.zeros((3, 3), np.int64)
    inv_ps = np.zeros(3)
    for k in range(d):
        loc[0, k], loc[1, k], loc[2, k] = cells[k], psize[k], ppa[k]
        inv_ps[k] = 1.0 / psize[k]
    result = (-1, 0)
    for dim in literal_unroll(DIMS):
        if dim == d:
            result = _locate_loop(dim, x, origin, inv_h, loc, inv_ps, current, out, order)
    return result


@loop_kernel
def _locate_loop(dim, x, origin, inv_h, loc, inv_ps, current, out, order):
    literally(dim)
    first = -1
    moved = 0
    for k in range(order.size):
        i = order[k]
        if dim == 1:
            pid = patch_id1(x[i, 0], origin, inv_h, loc, inv_ps)
        elif dim == 2:
            pid = patch_id2(x[i, 0], x[i, 1], origin, inv_h, loc, inv_ps)
        else:
            pid = patch_id3(x[i, 0], x[i, 1], x[i, 2], origin, inv_h, loc, inv_ps)
        if pid < 0:  # outside the grid (NaN too)
            out[i] = current[i]
            if first < 0:
                first = np.int64(i)
        else:
            out[i] = pid
            if pid != current[i]:
                moved += 1
    return first, moved
