"""What every particle file becomes (:class:`ParticleData`) and the checks every format shares:
finite numbers, positive volumes, det F > 0, at most :data:`MAX_PARTICLES` rows. A format's
reader says where row ``i`` is (``line 7`` of a CSV, ``row 6`` of an array) and what a field is
called in it (``column 'vx'``, ``dataset 'v'``), so each error is one line a user can act on.
"""
from __future__ import annotations

import difflib
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from parmpm.core.errors import SceneError
from parmpm.core.extremes import column_min_max
from parmpm.core.hash_mix import splitmix64_finish_kernel
from parmpm.core.jit import kernel

#: the most particles one file may hold: global ids and row counts are int64, but MPI counts
#: and numba loops over one rank's rows are int32 (2**31 - 1 rows of a ``count`` argument)
MAX_PARTICLES = 2**31

_AXES = "xyz"


def fail(label: str, message: str):
    """Raise the one-line error of file ``label``."""
    raise SceneError(" ".join(f"{label}: {message}".split()))


def number(value) -> str:
    """A value as an error shows it: shortest round-trip repr for floats."""
    return repr(float(value)) if isinstance(value, (float, np.floating)) else repr(value)


def suggest(name: str, known: list[str]) -> str:
    """``did you mean 'volume'?`` for a name close to one of ``known``, else the list of them."""
    close = difflib.get_close_matches(name.lower(), [k.lower() for k in known], n=1, cutoff=0.6)
    if close:
        return f"did you mean '{known[[k.lower() for k in known].index(close[0])]}'?"
    return f"expected one of {', '.join(known)}"


def check_count(label: str, n: int, what: str) -> None:
    """At most :data:`MAX_PARTICLES` particles, at least one."""
    if n > MAX_PARTICLES:
        fail(label, f"{what} holds {n} particles; at most {MAX_PARTICLES} (2**31) are supported "
                    "(split the body into several files)")
    if n == 0:
        fail(label, f"{what} holds no particles; expected at least one")


def check_finite(label: str, a: np.ndarray, where: Callable[[int], str], name: str) -> None:
    """Every value of ``a`` (rows = particles) finite: the first one that is not, named."""
    bad = ~np.isfinite(a)
    if bad.any():
        flat = int(np.flatnonzero(bad.reshape(a.shape[0], -1).any(axis=1))[0])
        value = a[flat].reshape(-1)[int(np.flatnonzero(bad[flat].reshape(-1))[0])]
        fail(label, f"{where(flat)}, {name}: value {number(value)} is not a finite number")


@dataclass(frozen=True, eq=False)
class ParticleData:
    """The particles of one file, in the file's row order (a parmpm snapshot or checkpoint: in
    global-id order). ``volume`` is each particle's *current* volume, as the file gives it (a
    snapshot's ``volume`` is ``vol0 · det F``); :meth:`reference_volume` is the volume before
    ``F`` (``volume / det F``), what seeding calls ``vol0``. Arrays are read-only float64
    (``material``: str names) and ``None`` where the file has no such field. ``source`` names
    what was read (the file, and which step of a run's output)."""

    x: np.ndarray
    volume: np.ndarray
    velocity: np.ndarray | None = None
    material: np.ndarray | None = None
    F: np.ndarray | None = None
    source: str = ""
    #: "" or the one line saying that rows repeat an earlier row's position (:func:`repeats`)
    repeats: str = ""

    def __post_init__(self):
        for name in ("x", "volume", "velocity", "material", "F"):
            a = getattr(self, name)
            if a is not None:
                a.setflags(write=False)

    @property
    def n(self) -> int:
        return int(self.x.shape[0])

    @property
    def dim(self) -> int:
        return int(self.x.shape[1])

    def reference_volume(self) -> np.ndarray:
        """``volume / det F`` (the volume itself without ``F``): V = V0 det F."""
        if self.F is None:
            return self.volume.copy()
        return self.volume / np.linalg.det(self.F)

    def describe(self) -> str:
        """One deterministic line for the log: count, total volume, bounds, optional fields."""
        lo, hi = column_min_max(self.x)
        bounds = ", ".join(f"{_AXES[a]} [{lo[a]:.6g}, {hi[a]:.6g}]" for a in range(self.dim))
        extra = [name for name in ("velocity", "F") if getattr(self, name) is not None]
        if self.material is not None:
            names, counts = np.unique(self.material, return_counts=True)
            extra.append("material " + ", ".join(f"{m} ({c})" for m, c in zip(names, counts)))
        tail = f"; {'; '.join(extra)}" if extra else ""
        return (f"{self.source}: {self.n} particles, total volume {self.volume.sum():.6g}, "
                f"bounds {bounds}{tail}")


def finish(label: str, source: str, fields: dict, where: Callable[[int], str],
           names: dict[str, str]) -> ParticleData:
    """Check the fields every format shares (``x`` (N, d), ``volume`` (N,) and the optional
    ``velocity``, ``material``, ``F``: finite, volume > 0, det F > 0), note repeated positions
    (:func:`repeats`) and freeze them.
    ``where(i)``: row ``i``'s place in the file; ``names``: each field's name in the file
    (``F`` may name one per component, ``names['F'](a, b)``)."""
    x = np.ascontiguousarray(fields["x"], dtype=np.float64)
    n, dim = x.shape
    vol = np.ascontiguousarray(fields["volume"], dtype=np.float64)
    v, F, mat = fields.get("velocity"), fields.get("F"), fields.get("material")
    for key, a in (("x", x), ("volume", vol), ("velocity", v), ("F", F)):
        if a is not None:
            check_finite(label, np.asarray(a), where, names[key])
    bad = np.flatnonzero(~(vol > 0))
    if bad.size:
        i = int(bad[0])
        fail(label, f"{where(i)}, {names['volume']}: volume {number(vol[i])} is not > 0; "
                    "expected every particle's volume > 0")
    if F is not None:
        F = np.ascontiguousarray(F, dtype=np.float64)
        det = np.linalg.det(F)
        bad = np.flatnonzero(~(det > 0))
        if bad.size:
            i = int(bad[0])
            fail(label, f"{where(i)}, {names['F']}: det F = {number(det[i])} is not > 0 (an "
                        "inverted or flattened particle); expected det F > 0")
    if v is not None:
        v = np.ascontiguousarray(v, dtype=np.float64)
    if mat is not None:
        mat = np.asarray(mat, dtype=str)
        empty = np.flatnonzero(np.char.str_len(np.char.strip(mat)) == 0)
        if empty.size:
            fail(label, f"{where(int(empty[0]))}, {names['material']}: empty material name; "
                        "expected the name of one of the scene's materials")
    return ParticleData(x=x, volume=vol, velocity=v, material=mat, F=F, source=source,
                        repeats=repeats(label, x, vol, where))


@kernel
def _repeated(x, bits, vol, table):
    """(rows that repeat an earlier row's position, their volume, the first such row, the row
    it repeats, the table slots probed): one pass through an open-addressing table of row
    numbers + 1. The row's key is finished with splitmix64's mixer, so the slot (its low bits)
    depends on every bit of every coordinate: a multiply alone leaves the low bits a function of
    the low mantissa bits only, which a lattice of binary fractions (0.5/m for m a power of two)
    has all zero, and its rows then queued behind each other in a few slots: 8,192 slots probed
    a row on a 256² lattice of binary fractions, 17,408 on one of integers, against 1.5 now
    (``tests/io/test_particle_repeats.py``)."""
    n, dim = x.shape
    mask = np.uint64(table.shape[0] - 1)
    count, added, first, orig, probed = 0, 0.0, -1, -1, 0
    for i in range(n):
        h = np.uint64(0)
        for a in range(dim):
            b = np.uint64(0) if x[i, a] == 0.0 else bits[i, a]  # -0.0 is 0.0
            h = (h ^ b) * np.uint64(0x9E3779B97F4A7C15)
        slot = splitmix64_finish_kernel(h) & mask
        while True:
            probed += 1
            j = np.int64(table[slot]) - 1
            if j < 0:
                table[slot] = i + 1
                break
            same = True
            for a in range(dim):
                if x[j, a] != x[i, a]:
                    same = False
                    break
            if same:
                if first < 0:
                    first, orig = i, j
                count += 1
                added += vol[i]
                break
            slot = (slot + np.uint64(1)) & mask
    return count, added, first, orig, probed


def repeated_rows(x: np.ndarray, vol: np.ndarray) -> tuple[int, float, int, int, int]:
    """:func:`_repeated` of the positions ``x`` (n, d) and volumes ``vol`` with a table of at
    least twice ``n`` slots: (count, volume added, first repeating row, the row it repeats,
    slots probed)."""
    n = x.shape[0]
    size = 1 << (2 * n - 1).bit_length()
    table = np.zeros(size, np.int32 if n < 2**31 - 1 else np.int64)
    return _repeated(x, x.view(np.uint64), vol, table)


def repeats(label: str, x: np.ndarray, vol: np.ndarray, where: Callable[[int], str]) -> str:
    """"" or one line: how many rows repeat an earlier row's position and the volume they add.
    The same position alone is enough: two particles of a body at one point are one point of
    the body seeded twice (its mass counted twice there), whatever else the rows say; a run's
    own output never holds two at one point. One pass, a hash table of the rows (``-0.0`` is
    ``0.0``)."""
    n = x.shape[0]
    if n < 2:
        return ""
    count, added, first, orig, _ = repeated_rows(x, vol)
    if not count:
        return ""
    total = float(vol.sum())
    return (f"{label}: {count} row(s) repeat an earlier row's position (the first: "
            f"{where(first)} repeats {where(orig)}); they add volume {added:.6g}, "
            f"{100 * added / total:.3g} % of the file's total {total:.6g} (each is one more "
            "particle, its mass counted again); remove them unless meant")
