"""HDF5 checkpoints: every particle field in global-id order, the resolved scene, the clock.

One file per checkpoint, ``checkpoint_<step>.h5``. PyPI's h5py is serial, so the run driver
gathers the particles to rank 0 in bounded blocks of global ids (no rank ever holds more than one
block of other ranks' particles) and rank 0 writes them here; restart reads the file back on any
number of ranks. The file is written under a temporary name, flushed, fsynced and renamed, so a
kill at any moment leaves every earlier checkpoint whole. Datasets are chunked with HDF5's
Fletcher-32 checksums, so flipped bytes are found on reading rather than restarted from.

Schema (format ``parmpm-checkpoint``, version 2), readable with plain h5py::

    /                 attrs: format, version, scene (resolved TOML), step, time, dt (last Δt),
                      vmax (max c+|v| for the next Δt), method, lcr (m, NaN = none), ranks
                      (that wrote it), particles, dim, state (JSON: metrics history, output
                      clock), digest (SHA-256 of the other attributes, see attrs_digest)
    /particles/gid    (N,) int64, = 0..N-1
    /particles/mat    (N,) int64 material row
    /particles/x, v, x0, lh0        (N, dim) float64
    /particles/mass, vol0, damage   (N,) float64
    /particles/F, stress, r0, rf    (N, dim, dim) float64 (rf: frozen CPDI domain, 0 = none;
                                    absent in version 1 files, read as 0)
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np

from parmpm.errors import ParmpmError

FORMAT = "parmpm-checkpoint"
VERSION = 2  # 2: adds particles/rf (frozen CPDI domains); version 1 files read with rf = 0
#: stored particle fields (``dx`` is MUSL scratch, ``patch`` is derived from ``x``)
FIELDS = ("gid", "mat", "x", "v", "x0", "mass", "vol0", "F", "stress", "r0", "lh0", "damage",
          "rf")
ATTRS = ("scene", "step", "time", "dt", "vmax", "method", "lcr", "ranks", "particles", "dim", "state")


def attrs_digest(attrs: dict) -> str:
    """SHA-256 of the root attributes (HDF5 checksums data chunks, not attributes)."""
    text = json.dumps({k: (v.item() if hasattr(v, "item") else v) for k, v in sorted(attrs.items())},
                      sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def checkpoint_name(step: int) -> str:
    return f"checkpoint_{step:08d}.h5"


class CheckpointWriter:
    """Rank 0's side of writing one checkpoint: create, take blocks, commit atomically."""

    def __init__(self, path: Path, n: int, like: dict[str, np.ndarray], attrs: dict):
        import h5py

        self.path = Path(path)
        self.tmp = self.path.with_name(self.path.name + ".tmp")
        try:
            self.f = h5py.File(self.tmp, "w")
        except OSError as exc:
            raise ParmpmError(f"cannot write checkpoint '{self.tmp}': {exc}") from None
        self.f.attrs["format"] = FORMAT
        self.f.attrs["version"] = VERSION
        for k, v in attrs.items():
            self.f.attrs[k] = v
        self.f.attrs["digest"] = attrs_digest({k: self.f.attrs[k] for k in ATTRS})
        g = self.f.create_group("particles")
        for name, a in like.items():
            shape = (n,) + a.shape[1:]
            chunk = (max(1, min(n, 65536)),) + a.shape[1:]
            g.create_dataset(name, shape=shape, dtype=a.dtype, chunks=chunk if n else None,
                             fletcher32=bool(n))

    def write(self, lo: int, block: dict[str, np.ndarray]) -> None:
        for name, a in block.items():
            self.f["particles"][name][lo:lo + a.shape[0]] = a

    def commit(self) -> None:
        self.f.flush()
        self.f.close()
        with open(self.tmp, "rb") as fh:
            os.fsync(fh.fileno())
        os.replace(self.tmp, self.path)
        try:
            dirfd = os.open(self.path.parent, os.O_RDONLY)
            os.fsync(dirfd)
            os.close(dirfd)
        except OSError:
            pass

    def abort(self) -> None:
        try:
            self.f.close()
        finally:
            self.tmp.unlink(missing_ok=True)


class CheckpointReader:
    """An open, validated checkpoint; every problem is a one-line ParmpmError naming the file."""

    def __init__(self, path):
        import h5py

        self.path = Path(path)
        where = f"checkpoint '{self.path}'"
        if not self.path.is_file():
            raise ParmpmError(f"{where}: no such file")
        try:
            self.f = h5py.File(self.path, "r")
        except OSError as exc:
            raise ParmpmError(f"{where}: not a readable HDF5 file (truncated or damaged?): "
                              f"{str(exc).splitlines()[0]}") from None
        a = self.f.attrs
        if a.get("format") != FORMAT:
            self.close()
            raise ParmpmError(f"{where}: not a parmpm checkpoint (no format = '{FORMAT}' attribute)")
        version = self.version = int(a.get("version", -1))
        if version > VERSION:
            self.close()
            raise ParmpmError(f"{where}: written by a newer parmpm (format version {version}; "
                              f"this parmpm reads up to {VERSION})")
        try:
            missing = [k for k in ATTRS + ("digest",) if k not in a]
            if missing or "particles" not in self.f:
                raise ParmpmError(f"{where}: damaged: missing {', '.join(missing) or 'particles group'}")
            self.attrs = {k: a[k] for k in ATTRS}
            if attrs_digest(self.attrs) != a["digest"]:
                raise ParmpmError(f"{where}: damaged: its attributes (scene, clock) fail their checksum")
            self._check_datasets(where)
        except ParmpmError:
            self.close()
            raise
        except Exception as exc:  # h5py reports damaged metadata in many ways
            self.close()
            raise ParmpmError(f"{where}: damaged ({type(exc).__name__}: "
                              f"{str(exc).splitlines()[0] if str(exc) else 'unreadable'})") from None
        self.where = where

    def _check_datasets(self, where: str) -> None:
        self.n = int(self.attrs["particles"])
        d = int(self.attrs["dim"])
        expected = {"gid": (), "mat": (), "mass": (), "vol0": (), "damage": (),
                    "x": (d,), "v": (d,), "x0": (d,), "lh0": (d,),
                    "F": (d, d), "stress": (d, d), "r0": (d, d)}
        if self.version >= 2:
            expected["rf"] = (d, d)
        g = self.f["particles"]
        for name, tail in expected.items():
            if name not in g or g[name].shape != (self.n,) + tail:
                got = g[name].shape if name in g else "nothing"
                raise ParmpmError(f"{where}: damaged: dataset particles/{name} is {got}, "
                                  f"expected {(self.n,) + tail}")

    @property
    def state(self) -> dict:
        return json.loads(str(self.attrs["state"]))

    def has(self, name: str) -> bool:
        """Whether the file holds ``particles/name`` (version 1 files have no ``rf``)."""
        return name in self.f["particles"]

    def read(self, name: str, lo: int = 0, hi: int | None = None) -> np.ndarray:
        try:
            return self.f["particles"][name][lo:hi]
        except Exception as exc:  # a Fletcher-32 mismatch, or damaged chunk index
            raise ParmpmError(f"{self.where}: damaged data in particles/{name} "
                              f"({str(exc).splitlines()[0]})") from None

    def close(self) -> None:
        self.f.close()


def prune(folder: Path, keep: int) -> None:
    """Delete all but the newest ``keep`` checkpoints (by step) in ``folder``."""
    files = sorted(Path(folder).glob("checkpoint_*.h5"))
    for old in files[:-keep] if keep > 0 else []:
        old.unlink(missing_ok=True)
