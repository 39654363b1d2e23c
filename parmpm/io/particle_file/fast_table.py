"""A CSV particle table read in one compiled pass (:mod:`parmpm.io.particle_file.scan`): the
header by the precise reader's own code, the rows from the bytes into float64 arrays, the
numbers ``float()`` alone can convert (``nan``, ``1_000``, > 19 digits) and the errors' line
numbers afterwards, for the few rows that need them. ``None`` where the file holds something the
pass leaves to the precise reader (:func:`parmpm.io.particle_file.table.read_precise`): its
header, or any byte the scan does not handle, so that errors keep their order and wording.
"""
from __future__ import annotations

import codecs

import numpy as np

import parmpm.io.particle_file.data as data
from parmpm.core.errors import SceneError
from parmpm.io.particle_file.data import fail, finish
from parmpm.io.particle_file.scan import BAIL, FIELDS, POW5, gather, line_of, scan
from parmpm.io.particle_file.table import (column_names, field_names, finite_floats, header,
                                           read_precise, split_fields)


def _header_line(raw: bytes, pos: int) -> tuple[int, str, int] | None:
    """(line number, text, offset after it) of the first meaningful line, if it and the lines
    before it are plain ASCII (a tab, a final ``\\r`` allowed)."""
    line = 1
    while pos < len(raw):
        end = raw.find(b"\n", pos)
        end = len(raw) if end < 0 else end
        seg = raw[pos:end].removesuffix(b"\r")
        if not seg.isascii() or any(c < 32 and c != 9 or c == 127 for c in seg):
            return None
        text = seg.decode("ascii")
        if text.strip() and not text.lstrip().startswith("#"):
            return line, text, end + 1
        line, pos = line + 1, end + 1
    return None


def _convert(label: str, raw: bytes, hard: np.ndarray, head: list[str], kinds: np.ndarray,
             comps: np.ndarray, dest: tuple, where) -> None:
    """The tokens the scan left (``hard``: row, file column, start, end) through ``float()``,
    column by column in the order the precise reader checks them (x, y, z, volume, velocities,
    F): the first non-number, then the first value that is not finite, named with its text."""
    order = sorted((k for k in range(len(head)) if kinds[k] >= 0), key=lambda k: (kinds[k], comps[k]))
    for k in order:
        rows = hard[hard[:, 1] == k]
        if not rows.size:
            continue
        name = head[k]
        texts = [raw[s:e].decode("ascii") for _, _, s, e in rows]
        values = finite_floats(label, name, texts, lambda i, rows=rows: where(int(rows[i, 0])))
        dest[kinds[k]][rows[:, 0], comps[k]] = values.view(np.uint64)


def _materials(buf: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    """The material column's names (str), from their tokens' bounds."""
    width = max(1, int((bounds[:, 1] - bounds[:, 0]).max()))
    table = gather(buf, bounds, width).view(f"S{width}").reshape(-1)
    names, inverse = np.unique(table, return_inverse=True)
    return np.array([n.decode("ascii") for n in names], dtype=str)[inverse.reshape(-1)]


def read_fast(label: str, path, raw: bytes, dim: int):
    """The fields of a CSV table's bytes and where each row is (``line 7``), or ``None``: the
    precise reader's to read. ``where`` reads the file again (errors and warnings only), so
    its bytes need not be kept."""
    start = len(codecs.BOM_UTF8) if raw.startswith(codecs.BOM_UTF8) else 0
    found = _header_line(raw, start)
    if found is None:
        return None
    line_no, text, pos = found
    comma = "," in text
    head = split_fields(text, comma)
    try:
        index = header(label, line_no, head, dim)
    except SceneError:
        return None  # the precise reader: the same error, after its checks of the whole file
    cap = raw.count(b"\n", pos) + 1
    if cap > data.MAX_PARTICLES:
        return None
    cols = column_names(dim)
    fields = [f for f in ("x", "volume", "velocity", "F") if cols[f][0] in index]
    kinds = np.full(len(head), -1, np.int64)
    comps = np.zeros(len(head), np.int64)
    for f, field in enumerate(fields):
        for c, name in enumerate(cols[field]):
            kinds[index[name]], comps[index[name]] = f, c
    dest = tuple(np.empty((cap, len(cols[f])), np.float64).view(np.uint64) for f in fields)
    mat = np.empty((cap if "material" in index else 0, 2), np.int64)
    buf = np.frombuffer(raw, np.uint8)
    status, rows, line, nfields, hard, nh = scan(buf, pos, line_no + 1, cap, comma, kinds, comps,
                                                 dest, mat, POW5)
    if status == BAIL:
        return None
    if status == FIELDS:
        fail(label, f"line {line}: {nfields} fields; expected {len(head)}, one per header column "
                    f"({', '.join(head)})")
    data.check_count(label, rows, "the table (a header, no rows)")

    def where(i: int, buf=None) -> str:
        buf = np.fromfile(path, np.uint8) if buf is None else buf
        return f"line {line_of(buf, pos, line_no + 1, i)}"

    canonical = {k: name for name, k in index.items()}  # 'X' in the file: column 'x'
    _convert(label, raw, hard[:nh], [canonical[k] for k in range(len(head))], kinds, comps,
             dest, lambda i: where(i, buf))
    out = {field: a[:rows].view(np.float64) for field, a in zip(fields, dest)}
    out["volume"] = out["volume"][:, 0]
    if "F" in out:
        out["F"] = out["F"].reshape(-1, dim, dim)
    if "material" in index:
        out["material"] = _materials(buf, mat[:rows])
    return out, where


def read_csv(label: str, path, dim: int):
    """The particles of the CSV table at ``path`` (:mod:`parmpm.io.particle_file.table`)."""
    try:
        raw = path.read_bytes()
    except OSError as exc:
        fail(label, f"cannot read: {exc.strerror or exc}")
    fast = read_fast(label, path, raw, dim)
    if fast is None:
        return read_precise(label, raw, dim)
    del raw  # the arrays alone from here on
    fields, where = fast
    return finish(label, label, fields, where, field_names(dim))
