"""The XML index of a snapshot series (``<name>.xdmf``), kept on disk while it grows.

The index lists every snapshot in two temporal collections (``domains``, then ``particles``:
meshio reads the last; :mod:`parmpm.io.xdmf` gives the layout). A run of 10⁴ snapshots has an
index of megabytes; held as an XML tree in memory it grew the run by ~50 kB per snapshot
(issue 28: RSS in a straight line with the snapshot count). Here a snapshot's grids are
serialised once, when it is added, and appended to one scratch file per collection, anonymous
files in the series' folder (removed by the system when closed, or when the process dies);
:meth:`XdmfIndex.write` assembles the index from them, a chunk at a time, and replaces the file
atomically. Memory stays flat however long the run; the text is byte for byte what
``ElementTree.indent`` and ``write`` gave for the whole tree.

Only *committed* snapshots reach the index: :meth:`XdmfIndex.add` appends whole snapshots and
remembers where each scratch file's committed text ends, so a snapshot whose write failed half
way (a full disk) is never listed.
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path
from xml.etree import ElementTree as ET

from parmpm.io.xdmf.layout import uniform_grid

#: the collections in file order (meshio's ``TimeSeriesReader`` reads the last one)
COLLECTIONS = ("domains", "particles")
_HEAD = "<?xml version='1.0' encoding='utf-8'?>\n<Xdmf Version=\"3.0\">\n  <Domain>\n"
_TAIL = "  </Domain>\n</Xdmf>"
_OPEN = '    <Grid Name="{}" GridType="Collection" CollectionType="Temporal"{}>\n'
_CLOSE = "    </Grid>\n"
_INDENT = "  "
_LEVEL = 3  # a snapshot's grid: Xdmf > Domain > collection > grid
_CHUNK = 1 << 20


def snapshot_grids(t: float, records: list[dict], parts: bool) -> dict[str, bytes]:
    """The text snapshot ``t`` adds to each collection: one uniform grid (one record), or a
    spatial collection of one uniform grid per part holding particles (``parts``); the
    ``domains`` collection only when a record has domain corners."""
    domains = any("domains" in r["arrays"] for r in records)
    out = {}
    for name, geometry, topology, center, wanted in (
            ("domains", "domains", "domains", "Cell", domains),
            ("particles", "x", "points", "Node", True)):
        if not wanted:
            continue
        if parts:
            grid = ET.Element("Grid", Name=name, GridType="Collection", CollectionType="Spatial")
            ET.SubElement(grid, "Time", Value=repr(float(t)))
            for rec in records:
                if rec["n"]:  # a part without particles: no grid (0 points upsets readers)
                    uniform_grid(grid, f"{name}_{rec['part']:05d}", t, rec, geometry, topology,
                                 center)
        else:
            holder = ET.Element("Grid")
            grid = uniform_grid(holder, name, t, records[0], geometry, topology, center)
        ET.indent(grid, space=_INDENT, level=_LEVEL)
        grid.tail = None
        out[name] = (_INDENT * _LEVEL + ET.tostring(grid, encoding="unicode") + "\n").encode()
    return out


class XdmfIndex:
    """The growing index of one series in ``folder``: :meth:`add` a snapshot's grids (from
    :func:`snapshot_grids`), :meth:`write` the index file, :meth:`close` the scratch files."""

    def __init__(self, folder: Path):
        self.folder = Path(folder)
        self._spill: dict[str, object] = {}  # collection -> scratch file (binary)
        self._end: dict[str, int] = {}        # collection -> bytes of committed snapshots

    def add(self, grids: dict[str, bytes]) -> None:
        """Append one snapshot's grids (an OSError propagates; the snapshot is then not
        committed and :meth:`write` leaves it out)."""
        for name, text in grids.items():
            f = self._spill.get(name)
            if f is None:
                f = self._spill[name] = tempfile.TemporaryFile(dir=self.folder)
                self._end[name] = 0
            f.seek(self._end[name])
            f.write(text)
        for name, text in grids.items():
            self._end[name] += len(text)

    def write(self, path: Path) -> None:
        """Write the index of every committed snapshot to ``path`` (atomically, through
        ``<path>.tmp``)."""
        path = Path(path)
        tmp = path.with_name(path.name + ".tmp")
        with open(tmp, "wb") as out:
            out.write(_HEAD.encode())
            for name in COLLECTIONS:
                f = self._spill.get(name)
                if f is None:
                    if name == "particles":  # an empty series: ElementTree's empty element
                        out.write(_OPEN.format(name, " /").encode())
                    continue
                out.write(_OPEN.format(name, "").encode())
                f.flush()
                f.seek(0)
                left = self._end[name]
                while left > 0:
                    chunk = f.read(min(left, _CHUNK))
                    if not chunk:
                        break
                    out.write(chunk)
                    left -= len(chunk)
                out.write(_CLOSE.encode())
            out.write(_TAIL.encode())
        os.replace(tmp, path)

    def close(self) -> None:
        """Close (and so remove) the scratch files; never raises."""
        spill, self._spill = self._spill, {}
        for f in spill.values():
            try:
                f.close()
            except OSError:
                pass


__all__ = ["XdmfIndex", "snapshot_grids", "COLLECTIONS"]
