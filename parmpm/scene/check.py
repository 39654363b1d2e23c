"""Checking primitives of the scene schema: one-line value formatting (TOML text), the ``l_cr``
spec parser and :class:`Checker`, whose checks raise a ``SceneError`` naming the scene, the
dotted key, the value and what was expected. :mod:`parmpm.scene.schema` builds the sections on
them. Pure Python: no numpy, no MPI.
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Callable
from typing import Any, NoReturn

from parmpm.core.errors import SceneError

AXIS_NAMES = "xyz"  # axis letters, in the order of the coordinates

#: the interpolators that cap their domains at ``method.lcr``
LCR_INTERPOLATORS = ("cpdi", "cpdi2")
LCR_EXPECTED = 'a positive length in metres, "<k>dx", "<k>dx/<n>" (k, n > 0) or "none"'
_LCR_RE = re.compile(r"^\s*(?P<k>[0-9.eE+-]*)\s*dx\s*(?:/\s*(?P<n>[0-9.eE+-]+)\s*)?$",
                     re.IGNORECASE)


# ---------------------------------------------------------------- value formatting (one line)

def _escape(text: str) -> str:
    """A TOML basic string: quotes, backslash and control characters (incl. DEL) escaped."""
    out = []
    for ch in text:
        if ch == '"':
            out.append('\\"')
        elif ch == "\\":
            out.append("\\\\")
        elif ch in "\n\t\r":
            out.append({"\n": "\\n", "\t": "\\t", "\r": "\\r"}[ch])
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04x}")
        else:
            out.append(ch)
    return '"' + "".join(out) + '"'


_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


def toml_key(key: str) -> str:
    """A TOML key: bare if it can be, else a quoted basic string."""
    return key if _BARE_KEY.fullmatch(key) else _escape(key)  # not match: "$" passes "0\n"


def toml_value(value: Any) -> str:
    """An inline TOML value (bool, int, float, str, list, dict) on one line."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)  # shortest round-tripping form; '1e-06', '1e+16' are valid TOML
    if isinstance(value, str):
        return _escape(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        inner = ", ".join(f"{toml_key(str(k))} = {toml_value(v)}" for k, v in value.items()
                          if v is not None)
        return "{ " + inner + " }" if inner else "{}"
    return _escape(repr(value))


def show(value: Any, limit: int = 80) -> str:
    """A value as it would be written in TOML, shortened for an error message."""
    text = toml_value(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


# ---------------------------------------------------------------- l_cr


def lcr_length(spec: Any, min_dx: float) -> float | None:
    """Critical CPDI length l_cr in metres from a scene spec; raises ``ValueError`` if bad.

    ``0.25`` -> 0.25 m; ``"2dx"`` -> 2·min_dx; ``"1.8dx/3"`` -> 0.6·min_dx; ``"dx"`` -> min_dx;
    ``"none"`` -> None (no domain scaling).
    """
    if isinstance(spec, bool):
        raise ValueError(LCR_EXPECTED)
    if isinstance(spec, (int, float)):
        if math.isfinite(spec) and spec > 0:
            return float(spec)
        raise ValueError(LCR_EXPECTED)
    if not isinstance(spec, str):
        raise ValueError(LCR_EXPECTED)
    if spec.strip().lower() == "none":
        return None
    match = _LCR_RE.match(spec)
    if not match:
        raise ValueError(LCR_EXPECTED)
    try:
        k = float(match["k"]) if match["k"] else 1.0
        n = float(match["n"]) if match["n"] else 1.0
    except ValueError:
        raise ValueError(LCR_EXPECTED) from None
    if not (math.isfinite(k) and math.isfinite(n) and k > 0 and n > 0):
        raise ValueError(LCR_EXPECTED)
    return k * min_dx / n


# ---------------------------------------------------------------- checker


class Checker:
    """Type/range checks that raise one-line ``SceneError``s naming scene, key and value."""

    def __init__(self, where: str, origins: dict[str, str]):
        self.where = where
        self.origins = origins  # dotted key -> the --set text that produced it

    def _origin(self, key: str) -> str:
        """The ``--set`` behind ``key``: the latest one that set it, a table above it or a key
        within it (``--set time.end=1 --set 'time={}'``: the second emptied the table)."""
        for okey, text in reversed(self.origins.items()):
            if key == okey or key.startswith(okey + ".") or okey.startswith(key + "."):
                return f" (from --set {short_text(text)})"
        return ""

    def fail(self, key: str, message: str) -> NoReturn:
        prefix = f"{key}: " if key else ""
        raise SceneError(one_line(f"{self.where}: {prefix}{message}{self._origin(key)}"))

    def expected(self, key: str, what: str, value: Any) -> NoReturn:
        self.fail(key, f"expected {what}, got {show(value)}")

    def table(self, key: str, value: Any, allowed: tuple[str, ...]) -> dict:
        """Check ``value`` is a table whose keys are all in ``allowed``."""
        if not isinstance(value, dict):
            self.expected(key, "a table", value)
        for name in value:
            if name not in allowed:
                full = f"{key}.{name}" if key else name
                close = difflib.get_close_matches(str(name), allowed, n=1, cutoff=0.6)
                hint = (f"did you mean '{key + '.' if key else ''}{close[0]}'?" if close
                        else "allowed: " + ", ".join(allowed))
                raise SceneError(one_line(
                    f"{self.where}: unknown key '{full}' ({hint}){self._origin(full)}"))
        return value

    def required(self, key: str, table: dict, name: str, what: str) -> Any:
        if table.get(name) is None:
            self.fail(f"{key}.{name}" if key else name, f"required key is missing (expected {what})")
        return table[name]

    def number(self, key: str, value: Any, what: str = "a number",
               ok: Callable[[float], bool] = lambda x: True) -> float:
        if (isinstance(value, bool) or not isinstance(value, (int, float))
                or not math.isfinite(value) or not ok(value)):
            self.expected(key, what, value)
        return float(value)

    def integer(self, key: str, value: Any, what: str = "an integer",
                ok: Callable[[int], bool] = lambda x: True) -> int:
        if isinstance(value, bool) or not isinstance(value, int) or not ok(value):
            self.expected(key, what, value)
        return value

    def string(self, key: str, value: Any, what: str = "a string") -> str:
        if not isinstance(value, str):
            self.expected(key, what, value)
        return value

    def boolean(self, key: str, value: Any) -> bool:
        if not isinstance(value, bool):
            self.expected(key, "true or false", value)
        return value

    def choice(self, key: str, value: Any, choices: tuple[str, ...]) -> str:
        if not isinstance(value, str) or value not in choices:
            self.expected(key, "one of " + ", ".join(f'"{c}"' for c in choices), value)
        return value

    def schedule(self, key: str, table: dict, time: dict, rows: int) -> tuple:
        """``(every, every_steps)`` of an output table's ``every`` (simulated s) and
        ``every_steps``; with neither, about ``rows`` per run of the resolved ``time``."""
        every, every_steps = table.get("every"), table.get("every_steps")
        if every is not None:
            every = self.number(f"{key}.every", every, "a number > 0 (s)", lambda x: x > 0)
        if every_steps is not None:
            every_steps = self.integer(f"{key}.every_steps", every_steps, "an integer > 0",
                                       lambda n: n > 0)
        if every is None and every_steps is None:
            if time["steps"] is not None:
                every_steps = max(1, time["steps"] // rows)
            else:
                every = time["end"] / rows
        return every, every_steps

    def vector(self, key: str, value: Any, dim: int, kind: str, broadcast: bool = True) -> list:
        """A per-axis list of length ``dim`` of ``kind`` items (see ``_KINDS``).

        A scalar is broadcast to every axis when ``broadcast`` (per-axis resolutions such as
        ``cells``), and otherwise accepted only in 1D (points and vectors such as ``g``).
        """
        singular, plural, is_int, ok = _KINDS[kind]
        what = f"{dim} {singular if dim == 1 else plural}"
        if not broadcast and dim > 1:
            what = f"a list of {what}"
        items = value if isinstance(value, list) else [value] * (dim if broadcast else 1)
        if len(items) != dim:
            self.expected(key, what, value)
        out = []
        for item in items:
            good = not isinstance(item, bool) and (
                isinstance(item, int) if is_int
                else isinstance(item, (int, float)) and math.isfinite(item))
            if not good or not ok(item):
                self.expected(key, what, value)
            out.append(item if is_int else float(item))
        return out


_KINDS = {  # kind -> (singular, plural, integer?, predicate)
    "float": ("number", "numbers", False, lambda x: True),
    "float>0": ("positive number", "positive numbers", False, lambda x: x > 0),
    "int>0": ("positive integer", "positive integers", True, lambda x: x > 0),
}


def one_line(text: str) -> str:
    return " ".join(text.splitlines())


def short_text(text: str, limit: int = 100) -> str:
    """``text`` on one line, cut to about ``limit`` characters for an error message (a
    5,000-digit ``--set`` value would fill the screen)."""
    text = one_line(str(text)).strip()
    if len(text) <= limit:
        return text
    return f"{text[:limit - 40]}... ({len(text)} characters)"
