"""A CSV table of particles: a header row naming the columns, one particle per row.

Columns (any order, names case-insensitive): ``x``, ``y``, ``z`` (as many as the scene's
dimensions) and ``volume``, required; ``vx``, ``vy``, ``vz`` (all or none); ``material`` (a
name); ``F11``, ``F12``, ... ``Fij`` = ∂x_i/∂X_j, 1-based, all dim² of them or none. Fields
are separated by commas (quoted as the csv module does), or by whitespace when the header has no
comma; spaces around fields, blank lines and lines starting with ``#`` are ignored. Errors name
the file's line (1-based, as an editor counts), the column and the value.

A table is read by one compiled pass over its bytes (:mod:`parmpm.io.particle_file.scan`:
seconds and its arrays once for 10⁷ rows); a file that pass does not handle (non-ASCII text,
quoted fields, control characters, a lone carriage return) by the precise reader below, row by
row in Python, which gives the same particles and the same errors.
"""
from __future__ import annotations

import csv

import numpy as np

import parmpm.io.particle_file.data as data
from parmpm.io.particle_file.data import fail, finish, suggest

_AXES = "xyz"


def column_names(dim: int) -> dict[str, list[str]]:
    """The columns of a ``dim``-D file, by field."""
    return {"x": list(_AXES[:dim]), "volume": ["volume"],
            "velocity": [f"v{a}" for a in _AXES[:dim]], "material": ["material"],
            "F": [f"F{i}{j}" for i in range(1, dim + 1) for j in range(1, dim + 1)]}


def _lines(label: str, raw: bytes) -> list[tuple[int, str]]:
    """The file's meaningful lines, numbered from 1 (blank and ``#`` lines dropped)."""
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        fail(label, f"is not UTF-8 text (byte 0x{raw[exc.start]:02x} at offset {exc.start}); "
                    "expected a CSV table")
    if "\0" in text:
        fail(label, f"holds a NUL byte at offset {text.index(chr(0))}; expected a CSV table")
    return [(k, s) for k, s in enumerate(text.splitlines(), 1)
            if s.strip() and not s.lstrip().startswith("#")]


def split_fields(line: str, comma: bool) -> list[str]:
    if not comma:
        return line.split()
    return [f.strip() for f in next(csv.reader([line], skipinitialspace=True))]


def header(label: str, line_no: int, names: list[str], dim: int) -> dict[str, int]:
    """Column name (canonical) → its index; every problem of the header row named."""
    known = {c.lower(): c for cols in column_names(dim).values() for c in cols}
    other = {c.lower(): (c, d) for d in (1, 2, 3) for cols in column_names(d).values()
             for c in cols}
    index: dict[str, int] = {}
    for k, name in enumerate(names):
        if not name:
            fail(label, f"line {line_no}: column {k + 1} of the header has no name; expected "
                        "a name for every column")
        key = name.lower()
        if key not in known:
            try:
                float(name)
                fail(label, f"line {line_no}: the first row must be a header naming the columns "
                            f"(x, ..., volume), found the number {name!r}")
            except ValueError:
                pass
            if key in other:
                fail(label, f"line {line_no}: column '{name}' is for a {other[key][1]}D scene, "
                            f"this scene is {dim}D; expected the columns "
                            f"{', '.join(known.values())}")
            fail(label, f"line {line_no}: unknown column '{name}'; "
                        f"{suggest(name, list(known.values()))}")
        canon = known[key]
        if canon in index:
            fail(label, f"line {line_no}: column '{name}' appears twice (columns "
                        f"{index[canon] + 1} and {k + 1}); expected each column once")
        index[canon] = k
    cols = column_names(dim)
    for field in ("x", "volume"):
        missing = [c for c in cols[field] if c not in index]
        if missing:
            fail(label, f"line {line_no}: no column '{missing[0]}'; a {dim}D particle file "
                        f"needs the columns {', '.join(cols['x'] + cols['volume'])}")
    for field in ("velocity", "F"):
        have = [c for c in cols[field] if c in index]
        if have and len(have) < len(cols[field]):
            missing = [c for c in cols[field] if c not in index]
            fail(label, f"line {line_no}: columns {', '.join(have)} but not "
                        f"{', '.join(missing)}; expected all {len(cols[field])} {field} "
                        "columns or none")
    return index


def _numbers(label: str, rows: list[list[str]], lines: list[int], k: int,
             name: str) -> np.ndarray:
    """Column ``k`` as float64; the first value that is no finite number named."""
    return finite_floats(label, name, [r[k] for r in rows], lambda i: f"line {lines[i]}")


def finite_floats(label: str, name: str, texts: list[str], where) -> np.ndarray:
    """``texts`` as float64 (``float()``'s reading); the first that is no number, then the first
    that is not finite, is one line naming ``where(i)`` (its place: "line N") and the column."""
    try:
        a = np.array(texts, dtype=np.float64)
    except ValueError:
        for i, s in enumerate(texts):
            try:
                float(s)
            except ValueError:
                fail(label, f"{where(i)}, column '{name}': {s!r} is not a number")
        raise
    bad = np.flatnonzero(~np.isfinite(a))
    if bad.size:
        i = int(bad[0])
        fail(label, f"{where(i)}, column '{name}': {texts[i]!r} is not a finite number")
    return a


def read_precise(label: str, raw: bytes, dim: int):
    """The particles of a CSV table's bytes, row by row (the reader of every file the fast
    pass leaves, and the one that names a bad row)."""
    lines = _lines(label, raw)
    if not lines:
        fail(label, "is empty (no header row); expected a header naming the columns "
                    f"({', '.join(column_names(dim)['x'])}, volume, ...) and one row per particle")
    comma = "," in lines[0][1]
    head = split_fields(lines[0][1], comma)
    index = header(label, lines[0][0], head, dim)
    if len(lines) - 1 > data.MAX_PARTICLES:
        data.check_count(label, len(lines) - 1, "the table")
    rows, numbers = [], []
    for line_no, text in lines[1:]:
        fields = split_fields(text, comma)
        if len(fields) != len(head):
            fail(label, f"line {line_no}: {len(fields)} fields; expected {len(head)}, one per "
                        f"header column ({', '.join(head)})")
        rows.append(fields)
        numbers.append(line_no)
    data.check_count(label, len(rows), "the table (a header, no rows)")
    cols = column_names(dim)
    out = {}
    for field in ("x", "volume", "velocity", "F"):
        if cols[field][0] in index:
            out[field] = np.stack([_numbers(label, rows, numbers, index[c], c)
                                   for c in cols[field]], axis=1)
    out["volume"] = out["volume"][:, 0]
    if "F" in out:
        out["F"] = out["F"].reshape(-1, dim, dim)
    if "material" in index:
        out["material"] = np.array([r[index["material"]] for r in rows], dtype=str)
    return finish(label, label, out, lambda i: f"line {numbers[i]}", field_names(dim))


def field_names(dim: int) -> dict[str, str]:
    """How an error names each field: ``columns x y``, ``column 'volume'``."""
    cols = column_names(dim)
    return {"x": "columns " + " ".join(cols["x"]), "volume": "column 'volume'",
            "velocity": "columns " + " ".join(cols["velocity"]), "material": "column 'material'",
            "F": "columns " + " ".join(cols["F"])}
