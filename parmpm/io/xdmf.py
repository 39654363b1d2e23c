"""XDMF time series of particles (meshio + HDF5), for ParaView.

Each snapshot is one uniform grid of the temporal collection holding its own geometry (particles
move, so unlike meshio's fixed-mesh time series every step has its own points), a ``Polyvertex``
topology (one vertex cell per particle) and the point data. The grids are written through the
internals of one ``meshio.xdmf.TimeSeriesWriter`` (its ``points``/``cells``/``point_data``
serialisers and its HDF5 naming); the heavy data goes to ``<name>.h5`` next to
``<name>.xdmf`` (meshio itself would put the .h5 in the working directory). The XML index is
rewritten atomically at most every ``flush_seconds`` and on :meth:`SnapshotWriter.close`, so a
crashed run still leaves a readable series of what was flushed.

Every failure to write (a full disk, a read-only folder, an I/O error) is one ``ParmpmError``
line, without a chained traceback: ``disk full writing '<name>.h5': N MB needed, M MB free``
when the free space (checked before each snapshot against its size) is short, or the system's
reason otherwise. The writer then closes: the index keeps the snapshots written before, and
:meth:`SnapshotWriter.close` does nothing more. HDF5 writes through
:class:`parmpm.io.guarded_file.GuardedFile`, so it never sees a failed write (HDF5 crashes the
process when it closes a file whose writes failed); a write error is found after each snapshot.

meshio's ``TimeSeriesReader`` reads it back: ``read_points_cells()`` gives the first snapshot's
geometry and ``read_data(k)`` the time and point data of snapshot ``k``.

Arrays are the gathered particle state (call from one rank); points are padded to 3D,
per-axis vectors ``(N, dim)`` to ``(N, 3)`` and tensors ``(N, dim, dim)`` to ``(N, 9)``
(row-major 3×3), which is what ParaView expects of ``Vector`` and ``Tensor`` attributes; in 1D
vectors and tensors are written as scalars (see :func:`pad_point_data`).
"""

from __future__ import annotations

import errno
import logging
import os
import shutil
import time
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np

from parmpm.errors import ParmpmError
from parmpm.io.guarded_file import GuardedFile, space_message

logger = logging.getLogger(__name__)

__all__ = ["SnapshotWriter", "pad_point_data"]


def _pad_columns(a: np.ndarray, width: int) -> np.ndarray:
    out = np.zeros((a.shape[0], width), dtype=np.float64)
    out[:, : a.shape[1]] = a
    return out


_XDMF_WIDTHS = (3, 6, 9)  # Vector, Tensor6, Tensor: the column counts XDMF names


def pad_point_data(name: str, data, n: int, dim: int) -> dict[str, np.ndarray]:
    """Shape one particle field for XDMF, as ``{name: array}`` (or several scalar columns).

    ``(N,)`` → scalar; ``(N, 1)`` and ``(N, 1, 1)`` (1D vectors and tensors) → scalar;
    ``(N, dim)`` → ``(N, 3)`` vector and ``(N, dim, dim)`` or ``(N, dim²)`` → ``(N, 9)``
    tensor (zero-padded, row-major 3×3); ``(N, 3)``, ``(N, 6)``, ``(N, 9)`` are kept; any
    other shape is flattened and written as scalar columns ``name_0``, ``name_1``, ... (XDMF has
    no attribute type for them). Booleans become int8, other non-float types float64.
    """
    a = np.asarray(data)
    if a.shape[:1] != (n,):
        raise ValueError(f"point data {name!r} has shape {a.shape}, expected {n} rows")
    if a.dtype.kind == "b":
        a = a.astype(np.int8)
    elif a.dtype.kind not in "iuf":
        a = a.astype(np.float64)
    a = a.reshape(n, -1)
    k = a.shape[1]
    if k == 1:
        return {name: np.ascontiguousarray(a[:, 0])}
    if dim < 3 and k == dim:
        return {name: _pad_columns(a, 3)}
    if dim < 3 and k == dim * dim:
        t = np.zeros((n, 3, 3), dtype=np.float64)
        t[:, :dim, :dim] = a.reshape(n, dim, dim)
        return {name: t.reshape(n, 9)}
    if k in _XDMF_WIDTHS:
        return {name: np.ascontiguousarray(a)}
    return {f"{name}_{j}": np.ascontiguousarray(a[:, j]) for j in range(k)}


class SnapshotWriter:
    """Write particle snapshots to ``<out_dir>/<name>.xdmf`` (+ ``<name>.h5``).

    ``write(t, x, point_data)`` adds one time step; ``close()`` finishes the files. Usable as a
    context manager. One ``meshio.xdmf.TimeSeriesWriter`` stays open across writes.
    """

    #: bytes a snapshot adds beyond its arrays (object headers, the group's index), bounded
    OVERHEAD = 64 * 1024

    def __init__(self, out_dir, name: str, dim: int, flush_seconds: float = 5.0):
        import h5py
        from meshio.xdmf import TimeSeriesWriter

        self.out_dir = Path(out_dir)
        self.dim = int(dim)
        self.path = self.out_dir / f"{name}.xdmf"
        self.h5_path = self.out_dir / f"{name}.h5"
        self.flush_seconds = float(flush_seconds)
        self.steps = 0
        self._last_flush = -np.inf
        self._closed = True  # until the files exist
        self._writer = TimeSeriesWriter(self.path, data_format="HDF")
        self._writer.h5_file = None
        self._file = None
        try:
            self.out_dir.mkdir(parents=True, exist_ok=True)
            # what TimeSeriesWriter.__enter__ does, but with the .h5 next to the .xdmf
            self._writer.h5_filename = str(self.h5_path)
            self._file = GuardedFile(self.h5_path)
            self._writer.h5_file = h5py.File(self._file, "w")
        except OSError as exc:
            self._fail(exc)
        self._closed = False
        self._check_io()

    # --- failures -----------------------------------------------------------------------------
    def _free(self) -> int | None:
        try:
            return int(shutil.disk_usage(self.out_dir).free)
        except OSError:
            return None

    def _check_io(self) -> None:
        """Raise the write error the guarded file kept, if any."""
        if self._file is not None and self._file.error is not None:
            self._fail(self._file.error)

    def _abandon(self) -> None:
        """Close the HDF5 file, ignoring errors (HDF5 cannot flush onto a full disk, and an
        unclosed file crashes the interpreter at exit), and stop writing."""
        self._closed = True
        h5, self._writer.h5_file = self._writer.h5_file, None
        if h5 is not None:
            try:
                h5.close()
            except Exception:  # noqa: BLE001 - the error being reported is the one that matters
                pass
        if self._file is not None:
            self._file.close()
        try:
            self.path.with_name(self.path.name + ".tmp").unlink(missing_ok=True)
        except OSError:
            pass

    def _fail(self, exc: BaseException, where: Path | None = None):
        """Abandon the files and raise the write error the guarded file kept (what h5py trips
        over after it is the consequence), else ``exc``, as one line; an ``exc`` that is no
        I/O error is re-raised (a bug)."""
        where = where or self.h5_path
        kept = self._file.error if self._file is not None else None
        self._abandon()
        if kept is None and not isinstance(exc, OSError):
            raise exc
        exc = kept or exc
        if exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG):
            free = self._free()
            tail = f": {free / 1e6:.1f} MB free" if free is not None else ""
            raise ParmpmError(f"disk full writing '{where}' ({os.strerror(exc.errno)}){tail}") from None
        why = os.strerror(exc.errno) if exc.errno else (str(exc).splitlines() or ["I/O error"])[0]
        raise ParmpmError(f"cannot write snapshots '{where}': {why}") from None

    # ----------------------------------------------------------------------------------------
    def write(self, t: float, x, point_data: dict | None = None) -> None:
        """Add the snapshot at time ``t``: positions ``x`` (N, dim) and named particle fields."""
        if self._closed:
            raise ValueError(f"{self.path} is closed")
        x = np.asarray(x, dtype=np.float64)
        n = x.shape[0]
        points = _pad_columns(x.reshape(n, -1), 3)
        vertices = np.arange(n, dtype=np.int64).reshape(n, 1)
        fields = {}
        for key, value in (point_data or {}).items():
            fields.update(pad_point_data(key, value, n, self.dim))
        need = points.nbytes + vertices.nbytes + sum(a.nbytes for a in fields.values()) + self.OVERHEAD
        free = self._free()
        if free is not None and need > free:
            try:  # stop cleanly: the index holds every snapshot written so far
                self.flush()
            except OSError:
                pass
            self._abandon()
            raise ParmpmError(space_message(self.h5_path, need, free))
        w = self._writer
        grid = ET.SubElement(w.collection, "Grid", Name=f"step{self.steps}", GridType="Uniform")
        try:
            ET.SubElement(grid, "Time", Value=repr(float(t)))
            w.points(grid, points)
            w.cells([("vertex", vertices)], grid)
            grid.find("Topology").set("NodesPerElement", "1")
            if fields:
                w.point_data(fields, grid)
        except Exception as exc:  # noqa: BLE001 - _fail re-raises what is not an I/O error
            w.collection.remove(grid)
            self._fail(exc)
        if self._file.error is not None:
            w.collection.remove(grid)
            self._fail(self._file.error)
        self.steps += 1
        now = time.monotonic()
        if now - self._last_flush >= self.flush_seconds:
            try:
                self.flush()
            except OSError as exc:
                self._fail(exc)

    def flush(self) -> None:
        """Flush the HDF5 data and atomically rewrite the XML index (an OSError propagates;
        :meth:`write` and :meth:`close` turn it into one line). The index is not rewritten when
        the data did not reach the disk."""
        self._writer.h5_file.flush()
        if self._file.error is not None:
            raise self._file.error
        tmp = self.path.with_name(self.path.name + ".tmp")
        ET.ElementTree(self._writer.xdmf_file).write(tmp)
        os.replace(tmp, self.path)
        self._last_flush = time.monotonic()

    def close(self) -> None:
        """Write the final XML index and close the HDF5 file (idempotent)."""
        if self._closed:
            return
        try:
            self.flush()
            h5, self._writer.h5_file = self._writer.h5_file, None
            self._closed = True
            h5.close()
            self._check_io()
            self._file.close()
            self._check_io()
        except OSError as exc:
            self._fail(exc)
        logger.debug("wrote %d snapshots to %s", self.steps, self.path)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False
