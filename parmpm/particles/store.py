"""Particle store: structure of arrays, grouped by patch (CSR offsets), global-id order inside a
patch.

Fields use the literature's names: ``x`` position, ``v`` velocity, ``x0`` reference position,
``mass``, ``vol0`` initial volume, ``F`` deformation gradient, ``stress`` (Cauchy), ``r0`` initial
CPDI domain vectors (columns, physical units), ``lh0`` initial GIMP half-widths, ``mat`` material
row, ``damage`` (for damage models), ``rf`` a frozen CPDI domain in the material's unrotated
frame (zeros: not frozen; :mod:`parmpm.shapes.freeze`), ``affine`` the APIC affine velocity
matrix ``C_p = B_p D_p⁻¹`` (Jiang et al. 2015; zeros under FLIP: :mod:`parmpm.transfer.affine`),
``corners`` the CPDI2 domain's corners minus the particle's position ``(2^d, d)`` (physical
units, the bit order of :mod:`parmpm.shapes.cpdi2`; moved by the grid in G2P), ``plastic`` a
plastic material's state row (:mod:`parmpm.materials.plasticity.state`), ``gid`` global id (never changes: it is
how runs on different rank counts and restarts are compared), ``dx`` a scratch displacement for
MUSL.
"""
from __future__ import annotations

import numpy as np

from parmpm.materials.plasticity.state import STATE_WIDTH
from parmpm.particles.order import LEFT, merge_order, move_runs

FLOAT_FIELDS = ("x", "v", "x0", "mass", "vol0", "F", "stress", "r0", "lh0", "damage", "dx", "rf",
                "affine", "corners", "plastic")
INT_FIELDS = ("gid", "mat", "patch")
#: fields only the runs that need them carry (elsewhere zero rows, never moved or stored):
#: ``affine`` under APIC, ``corners`` under cpdi2, ``plastic`` with a plastic material (zeros
#: when first carried: the set-up writes the virgin state)
OPTIONAL_FIELDS = ("affine", "corners", "plastic")


class Particles:
    """SoA particle arrays of one rank, grouped by local patch slot (``start``: CSR offsets into
    :meth:`order`) and sorted by global id inside a patch. ``patch`` is the global id of the
    particle's patch.

    Reading a field (``P.x``) always gives the rows in that canonical order. The time step
    works on the rows as they lie (:attr:`rows`) and visits them through :meth:`order`
    (:mod:`parmpm.particles.order`): after particles change patch or rank only the index moves,
    and the fields are copied into order (:meth:`compact`) when a field is read from outside the
    step or once :data:`COMPACT_FRACTION` of the rows are out of place. The arrays may be views
    of longer buffers (room for arriving rows without a reallocation)."""

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
        self._order_bufs = [np.zeros(0, np.uint64), np.zeros(0, np.uint64)]
        self._order_in = -1  # which of _order_bufs ``_order`` lies in (-1: neither)
        self._flags = np.zeros(0, np.uint8)  # merge_order's zeroed scratch byte per row
        self._scratch = np.zeros((4, 0), np.int64)  # merge_order's lists (prefixes touched)
        #: longer arrays the fields are views of (None: the fields are exact-size arrays)
        self._buf: dict[str, np.ndarray] | None = None
        #: ``start`` and the order group the rows by their ``patch`` (False after arbitrary
        #: replacements, until :meth:`group_by_patch` regroups them)
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
        a["plastic"] = np.zeros((n if "plastic" in optional else 0, STATE_WIDTH))
        a["patch"] = np.zeros(n, np.int64)
        self.rows = _Rows(a)
        self.start = np.zeros(1, np.int64)

    @property
    def n(self) -> int:
        return self._a["gid"].size

    def names(self) -> tuple[str, ...]:
        """The fields this store carries: every field but the optional ones it does not."""
        return INT_FIELDS + tuple(k for k in FLOAT_FIELDS
                                  if k not in OPTIONAL_FIELDS or k in self.optional)

    # --- canonical order ------------------------------------------------------------------------
    def order(self) -> np.ndarray:
        """Canonical position -> physical row (uint64, what the kernels loop over: patch slot
        ``s`` is ``order[start[s]:start[s + 1]]``); the identity while the rows are compact."""
        if self._order is not None:
            return self._order
        if self._identity.size != self.n:
            self._identity = np.arange(self.n, dtype=np.uint64)
        return self._identity

    def lazy_order(self) -> np.ndarray | None:
        """:meth:`order`, or None while the rows lie in canonical order: the kernels take it as
        an argument, so numba compiles a loop that indexes the rows directly (a load and a
        select fewer per particle: 8 % of 2D mpm's P2G)."""
        return self._order

    def compact(self) -> None:
        """Put the rows into canonical (slot, gid) order (a no-op when they are): every field is
        read through this, so code outside the time step never sees the lazy order."""
        if self._order is None:
            return
        order = self._order.astype(np.int64)
        n = order.size
        # as long as the buffers were: room for arrivals where rows come and go (the exchange
        # made it), none where they never did
        rows = n if self._buf is None else max(n, self._buf["gid"].shape[0])
        buf, self._buf = {}, None  # each old array goes as its field is replaced
        for name in self.names():
            a = self._a[name]
            b = np.empty((rows,) + a.shape[1:], a.dtype)
            np.take(a, order, axis=0, out=b[:n], mode="clip")  # "raise" buffers a copy
            buf[name] = b
            self._a[name] = b[:n]
        self._buf = buf
        self._set_order(None)
        self.displaced = 0

    def _set_order(self, order: np.ndarray | None, into: int = -1) -> None:
        self._order, self._order_in = order, into

    def _order_buffer(self, n: int) -> tuple[np.ndarray, int]:
        """An ``n``-long uint64 array to write the next order into (never the current one)."""
        k = 1 if self._order_in == 0 else 0
        if self._order_bufs[k].size < n:
            self._order_bufs[k] = np.empty(_room(n), np.uint64)
        return self._order_bufs[k][:n], k

    def _scratch_rows(self, n: int) -> np.ndarray:
        if self._scratch.shape[1] < n:
            self._scratch = np.empty((4, _room(n)), np.int64)
        return self._scratch

    def _flag_bytes(self, n: int) -> np.ndarray:
        if self._flags.size < n:
            self._flags = np.zeros(_room(n), np.uint8)
        return self._flags

    # --- whole-store changes --------------------------------------------------------------------
    def carry(self, optional: tuple[str, ...]) -> None:
        """Carry exactly the optional fields ``optional`` (a new one starts at zero): a restart
        from a checkpoint that lacks one (an older format) still runs."""
        self.compact()
        self._buf = None
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
        self._set_order(None)
        self.displaced, self._grouped, self._buf = 0, False, None
        for name, arr in fields.items():
            self._a[name] = arr

    def permute(self, perm: np.ndarray) -> None:
        """Reorder (or select) every field by ``perm``, one field at a time (so at most one
        field's worth of extra memory is held: the old array goes as soon as it is replaced)."""
        self.compact()
        self._grouped, self._buf = False, None
        for name in self.names():
            self._a[name] = np.take(self._a[name], perm, axis=0)

    # --- regrouping after a step ----------------------------------------------------------------
    def group_by_patch(self, new_patch: np.ndarray, slot_of: np.ndarray, n_slots: int,
                       force: bool = False, moved: int = -1, keep: np.ndarray | None = None,
                       received: dict | None = None) -> bool:
        """Group by (local slot of the global patch id, gid) and rebuild the CSR offsets; a no-op
        when no particle changed patch or rank (and not ``force``). Returns True if the order
        changed. The order inside a patch depends only on the patch's particles, never on the
        rank.

        ``new_patch``: every row's next patch (it becomes the store's ``patch`` array unless
        rows left); ``moved``: how many changed patch, when the caller counted them; after an
        exchange, ``keep`` (increasing) are the rows that stay on this rank and ``received`` the
        arrived records. Lazily (:mod:`parmpm.particles.order`): the new order is merged in O(n)
        from the old one and the rows that changed patch; rows that left are filled from the
        tail, received rows appended; the fields are copied into order (:meth:`compact`) only
        once more than :data:`COMPACT_FRACTION` of the rows sit out of place."""
        a = self._a
        exchanged = keep is not None or received is not None
        if force or not self._grouped or self.start.size != n_slots + 1:
            if exchanged:
                raise ValueError("group_by_patch: an exchange needs the rows grouped first")
            self._sort_by_patch(new_patch, slot_of, n_slots)
            return True
        if not exchanged and (moved == 0 or (moved < 0 and np.array_equal(new_patch, a["patch"]))):
            return False
        self._merge_by_patch(new_patch, slot_of, keep, received)
        return True

    def _sort_by_patch(self, new_patch: np.ndarray, slot_of: np.ndarray, n_slots: int) -> None:
        """The full regrouping: a new slot map of unchanged rows, or a stable sort by (slot, gid)
        of the compacted fields."""
        a = self._a
        if not (self._grouped and new_patch is a["patch"] and self._reslot(slot_of, n_slots)):
            self.compact()
            slot = slot_of[new_patch]
            key = slot * (int(a["gid"].max(initial=0)) + 1) + a["gid"]
            a["patch"] = new_patch
            self.permute(np.argsort(key, kind="stable"))
            counts = np.bincount(slot, minlength=n_slots)
            self.start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        self._grouped = True

    def _merge_by_patch(self, new_patch: np.ndarray, slot_of: np.ndarray,
                        keep: np.ndarray | None, received: dict | None) -> None:
        """The lazy regrouping of :meth:`group_by_patch`: the order merged in O(n), rows that
        left filled from the tail, received rows appended, compacted past the threshold."""
        a = self._a
        n = self.n
        empty = np.zeros(0, np.int64)
        keep = np.arange(n) if keep is None else np.asarray(keep, np.int64)
        n_keep = keep.size
        r = 0 if received is None else int(received["gid"].shape[0])
        flags = self._flag_bytes(n)
        holes = fillers = empty
        if n_keep < n:
            gone = np.ones(n, bool)
            gone[keep] = False
            leavers = np.flatnonzero(gone)
            flags[leavers] = LEFT
            holes, fillers = leavers[leavers < n_keep], keep[keep >= n_keep]
        counts = np.diff(self.start)
        out, into = self._order_buffer(n_keep + r)
        changed = merge_order(self.order(), a["patch"], new_patch, slot_of, a["gid"],
                              self.start, counts, flags, fillers, holes,
                              slot_of[received["patch"]] if r else empty,
                              received["gid"] if r else empty, self._scratch_rows(n + r),
                              out)
        if n_keep == n and r == 0:
            a["patch"] = new_patch
        else:
            self._move_rows(new_patch, holes, fillers, received, n_keep + r)
        self._set_order(out, into)
        self.start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        self.displaced += changed + r
        if self.displaced > COMPACT_FRACTION * self.n:
            self.compact()

    def _move_rows(self, new_patch, holes, fillers, received, n_new) -> None:
        """Rows ``fillers`` (kept rows past the new kept count) into the rows that left
        (``holes``), the received rows after the kept ones; ``new_patch`` gives the kept rows'
        patches. Buffers grow by an eighth more than needed when the rows outgrow them (one copy)."""
        a = self._a
        n_keep = n_new - (0 if received is None else int(received["gid"].shape[0]))
        grow = self._buf is None or self._buf["gid"].shape[0] < n_new
        buf = {} if grow else self._buf
        self._buf = None  # when growing, each old array goes as its field is replaced
        for name in self.names():
            src = new_patch if name == "patch" else a[name]
            if holes.size:
                src[holes] = src[fillers]
            if grow:
                buf[name] = np.empty((_room(n_new),) + src.shape[1:], src.dtype)
            dst = buf[name]
            if grow or name == "patch":
                dst[:n_keep] = src[:n_keep]
            if received is not None:
                dst[n_keep:n_new] = received[name]
            a[name] = dst[:n_new]
        self._buf = buf

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
        out, into = self._order_buffer(self.n)
        move_runs(self.order(), old[full], sizes[full], start[to], out)
        self._set_order(out, into)
        self.start = start
        return True


#: rows moved out of canonical place (counted since the last copy, relative to the rows held)
#: at which :meth:`Particles.group_by_patch` copies every field into canonical order. Measured
#: (10⁶ 2D CPDI particles, ``bench --speed 100``, ~0.8 % of the rows changing patch per step,
#: 120 steps, one core): the same P2G and G2P times with the copy at 25 %, 50 % and 100 % (the
#: misplaced rows come in runs), and the sort's share 4.9, 4.7 and 3.8 % (a copy: 60–130 ms)
COMPACT_FRACTION = 1.0


def _room(n: int) -> int:
    """Rows to allocate for ``n`` when they grow: an eighth more."""
    return n + n // 8 + 64


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
        self._buf = None  # the fields are no longer all views of the buffers
        self._a[name] = value
    return property(get, put, doc=f"``{name}``, rows in canonical order")


for _name in INT_FIELDS + FLOAT_FIELDS:
    setattr(Particles, _name, _field(_name))
