"""Scene schema, loads and walls: ``[[loads]]`` (body forces, point loads, tractions, pressure)
and ``[[walls]]`` (rigid planes at any angle, fixed or moving, with Coulomb friction), each with a
time function, checked key by key and resolved into the records :class:`Load` and :class:`Wall`.

    [[walls]]
    name = "slope"                  # names the history columns (default "wall<i>")
    point = [0.0, 0.0]              # a point of the plane
    normal = [-0.5, 0.866]          # out of the wall, towards the bodies (any length)
    friction = 0.1                  # Coulomb's μ >= 0, or "stick"
    velocity = [0.0, -0.01]         # optional: the plane moves (a plate, an indenter), m/s
    time = {function = "ramp", duration = 0.01}   # scales the velocity (default constant)

    [[loads]]
    kind = "traction"               # "body_force" | "point" | "traction" | "pressure"
    body = 0                        # index in [[bodies]] (body_force: default every body)
    region = {min = [..], max = [..]}  # traction, pressure: only the faces inside this box
    normal = [1.0, 0.0]             # traction, pressure: only the faces facing this way
    value = [1e6, 0.0]              # body_force m/s², point N, traction Pa
    pressure = 1e5                  # pressure only: Pa, > 0 pushes into the body
    at = [0.5, 1.0]                 # point only: the particle nearest this point at the start
                                    # (inside the grid)
    time = {function = "table", points = [[0.0, 0.0], [0.1, 1.0]]}

Every problem is one line naming the full key (``loads.1.value``), the value and what was
expected. What the loads do is :mod:`parmpm.loads.external`, the walls :mod:`parmpm.grid.walls`;
``docs/concepts/loads.md`` derives both.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from parmpm.loads.time_functions import FUNCTIONS, TimeFunction
from parmpm.scene.check import Checker, show

WALL_KEYS = ("name", "point", "normal", "friction", "velocity", "time")
LOAD_KEYS = ("name", "kind", "body", "region", "normal", "value", "pressure", "at", "time")
LOAD_KINDS = ("body_force", "point", "traction", "pressure")
TIME_FUNCTION_KEYS = ("function", "duration", "points")
#: the most rows of a time function's table, walls and loads in a scene
MAX_TABLE = 10_000
MAX_WALLS = 64
MAX_LOADS = 256
#: the fastest a wall may move (m/s): beyond any wave speed a solid carries
MAX_WALL_SPEED = 1e6
#: the largest load magnitude (a body force in m/s², a traction in Pa, a force in N)
MAX_LOAD = 1e30


@dataclass(frozen=True, slots=True)
class Wall:
    """A rigid plane through ``point`` with unit ``normal`` (out of the wall), Coulomb's
    ``friction`` (a number, or "stick"), moving at ``velocity`` scaled by ``time``."""

    name: str
    point: tuple[float, ...]
    normal: tuple[float, ...]
    friction: float | str
    velocity: tuple[float, ...]
    time: TimeFunction

    @property
    def moves(self) -> bool:
        return any(v != 0.0 for v in self.velocity)

    @property
    def mu(self) -> float:
        return math.inf if self.friction == "stick" else float(self.friction)


@dataclass(frozen=True, slots=True)
class Region:
    """The box ``min``-``max`` a traction's or pressure's faces are taken in."""

    min: tuple[float, ...]
    max: tuple[float, ...]


@dataclass(frozen=True, slots=True)
class Load:
    """One ``[[loads]]`` table (module doc); the fields another kind does not use are None."""

    name: str
    kind: str
    time: TimeFunction
    body: int | None = None
    region: Region | None = None
    value: tuple[float, ...] | None = None
    pressure: float | None = None
    at: tuple[float, ...] | None = None
    normal: tuple[float, ...] | None = None


def check_time(c: Checker, key: str, raw: Any) -> dict:
    """A time function table (:mod:`parmpm.loads.time_functions`)."""
    t = c.table(key, raw, TIME_FUNCTION_KEYS)
    function = c.choice(f"{key}.function", t.get("function", "constant"), FUNCTIONS)
    out: dict[str, Any] = {"function": function}
    needs = {"ramp": "duration", "smooth_step": "duration", "table": "points"}.get(function)
    for name in ("duration", "points"):
        if name in t and name != needs:
            c.fail(f"{key}.{name}", f'not used by function "{function}"'
                                    + (f" (expected {needs})" if needs else ""))
    if needs == "duration":
        out["duration"] = c.number(f"{key}.duration", c.required(key, t, "duration",
                                                                 "a number > 0 (s)"),
                                   "a number > 0 (s)", lambda x: x > 0)
    elif needs == "points":
        out["points"] = _table(c, f"{key}.points", c.required(key, t, "points",
                                                              "a list of [t, f] pairs"))
    return out


def _table(c: Checker, key: str, raw: Any) -> list:
    what = f"a list of 1 to {MAX_TABLE} pairs [t, f] with increasing times t >= 0"
    if not isinstance(raw, list) or not 1 <= len(raw) <= MAX_TABLE:
        c.expected(key, what, raw)
    out = []
    for i, pair in enumerate(raw):
        if not isinstance(pair, list):
            c.expected(f"{key}.{i}", "a pair [t, f] of numbers", pair)
        t, f = c.vector(f"{key}.{i}", pair, 2, "float", False)
        if t < 0 or (out and t <= out[-1][0]):
            c.expected(f"{key}.{i}", f"a time >= 0 and after the row before "
                                     f"({out[-1][0]:g} s)" if out else "a time >= 0", pair)
        if abs(f) > MAX_LOAD:
            c.expected(f"{key}.{i}", f"a factor of magnitude <= {MAX_LOAD:g}", pair)
        out.append([t, f])
    return out


def _unit(c: Checker, key: str, v: list) -> list:
    """``v`` scaled to unit length (scaled by its largest component first: 1e308 and 1e-320
    stay finite and nonzero)."""
    big = max(abs(x) for x in v)
    if big == 0.0:
        c.expected(key, "a nonzero vector", v)
    w = [x / big for x in v]
    n = math.sqrt(sum(x * x for x in w))
    return [x / n for x in w]


def _name(c: Checker, key: str, t: dict, default: str, taken: set) -> str:
    name = c.string(f"{key}.name", t.get("name", default))
    if not name or not all(ch.isalnum() or ch in "_-" for ch in name) or len(name) > 40:
        c.expected(f"{key}.name", "1 to 40 letters, digits, '_' or '-' (it names history "
                                  "columns)", name)
    if name in taken:
        c.fail(f"{key}.name", f"{show(name)} is used twice (each wall and load needs its own)")
    taken.add(name)
    return name


def check_walls(c: Checker, raw: Any, dim: int, taken: set) -> list:
    """The resolved ``[[walls]]``."""
    if not isinstance(raw, list) or len(raw) > MAX_WALLS:
        c.expected("walls", f"an array of at most {MAX_WALLS} tables [[walls]]", raw)
    out = []
    for i, item in enumerate(raw):
        key = f"walls.{i}"
        t = c.table(key, item, WALL_KEYS)
        pts = f"{dim} numbers"
        point = c.vector(f"{key}.point", c.required(key, t, "point", pts), dim, "float", False)
        normal = _unit(c, f"{key}.normal", c.vector(
            f"{key}.normal", c.required(key, t, "normal", pts), dim, "float", False))
        friction = t.get("friction", 0.0)
        if friction != "stick":
            friction = c.number(f"{key}.friction", friction, 'a number >= 0 or "stick"',
                                lambda x: x >= 0)
        velocity = c.vector(f"{key}.velocity", t.get("velocity", [0.0] * dim), dim, "float",
                            False)
        if math.hypot(*velocity) > MAX_WALL_SPEED:
            c.expected(f"{key}.velocity", f"a speed <= {MAX_WALL_SPEED:g} m/s", velocity)
        time = check_time(c, f"{key}.time", t.get("time", {}))
        if time["function"] != "constant" and not any(velocity):  # it would be ignored
            c.fail(f"{key}.time", f'a fixed wall has no use for function "{time["function"]}" '
                                  f"(a time function scales the velocity; give {key}.velocity "
                                  "to move the wall, or leave time out)")
        out.append({"name": _name(c, key, t, f"wall{i}", taken), "point": point,
                    "normal": normal, "friction": friction, "velocity": velocity,
                    "time": time})
    return out


def check_loads(c: Checker, raw: Any, dim: int, bodies: list, taken: set,
                grid: dict | None = None) -> list:
    """The resolved ``[[loads]]`` (``grid``: the resolved ``[grid]``, which a point load's
    ``at`` must lie in)."""
    if not isinstance(raw, list) or len(raw) > MAX_LOADS:
        c.expected("loads", f"an array of at most {MAX_LOADS} tables [[loads]]", raw)
    out = []
    for i, item in enumerate(raw):
        key = f"loads.{i}"
        t = c.table(key, item, LOAD_KEYS)
        kind = c.choice(f"{key}.kind", c.required(key, t, "kind", "a load kind"), LOAD_KINDS)
        uses = {"body_force": ("body", "value"), "point": ("value", "at"),
                "traction": ("body", "region", "normal", "value"),
                "pressure": ("body", "region", "normal", "pressure")}[kind]
        for name in ("body", "region", "normal", "value", "pressure", "at"):
            if name in t and name not in uses:
                c.fail(f"{key}.{name}", f'not used by kind "{kind}" (expected '
                                        f"{' and '.join(uses)})")
        load: dict[str, Any] = {"name": _name(c, key, t, f"load{i}", taken), "kind": kind,
                                "time": check_time(c, f"{key}.time", t.get("time", {}))}
        if "body" in t or kind in ("traction", "pressure"):
            load["body"] = c.integer(f"{key}.body", c.required(key, t, "body", "a body index"),
                                     f"an index in [[bodies]] (0 to {len(bodies) - 1})",
                                     lambda b: 0 <= b < len(bodies))
        if "value" in uses:
            value = c.vector(f"{key}.value", c.required(key, t, "value", f"{dim} numbers"),
                             dim, "float", False)
            if max(abs(v) for v in value) > MAX_LOAD:
                c.expected(f"{key}.value", f"components of magnitude <= {MAX_LOAD:g}", value)
            load["value"] = value
        if kind == "pressure":
            load["pressure"] = c.number(f"{key}.pressure", c.required(
                key, t, "pressure", "a number (Pa)"), f"a number of magnitude <= {MAX_LOAD:g} "
                "(Pa; > 0 pushes into the body)", lambda x: abs(x) <= MAX_LOAD)
        if kind == "point":
            load["at"] = c.vector(f"{key}.at", c.required(key, t, "at", f"{dim} numbers"), dim,
                                  "float", False)
            if grid is not None:
                _in_grid(c, f"{key}.at", load["at"], grid)
        if "normal" in t:  # absent when not given: older scenes resolve as they did
            load["normal"] = _unit(c, f"{key}.normal", c.vector(f"{key}.normal", t["normal"],
                                                                dim, "float", False))
        if "region" in t:
            r = c.table(f"{key}.region", t["region"], ("min", "max"))
            rk = f"{key}.region"
            lo = c.vector(f"{rk}.min", c.required(rk, r, "min", f"{dim} numbers"), dim, "float",
                          False)
            hi = c.vector(f"{rk}.max", c.required(rk, r, "max", f"{dim} numbers"), dim, "float",
                          False)
            if any(b < a for a, b in zip(lo, hi)):
                c.expected(f"{rk}.max", f"each component >= {rk}.min {show(lo)}", hi)
            load["region"] = {"min": lo, "max": hi}
        out.append(load)
    return out


def _in_grid(c: Checker, key: str, at: list, grid: dict) -> None:
    """A point load's ``at`` inside the grid: from outside it the nearest particle is wherever
    the bodies' edge is (6 m away took the nearest particle; issue 41)."""
    lo = [float(o) for o in grid["origin"]]
    hi = [o + n * h for o, n, h in zip(lo, grid["cells"], grid["cell_size"])]
    if any(not a <= x <= b for x, a, b in zip(at, lo, hi)):
        box = " to ".join("[" + ", ".join(f"{x:.6g}" for x in v) + "]" for v in (lo, hi))
        c.expected(key, f"a point inside the grid {box}", at)
