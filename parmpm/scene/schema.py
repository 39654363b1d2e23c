"""Scene schema: defaults, validation and resolution of a raw (parsed TOML) scene.

``resolve(raw, where)`` turns the nested dict read from a scene file (after ``--set`` overrides)
into the *resolved* scene: every optional key present (``None`` where the schema says "no value"),
per-axis quantities broadcast to lists of length ``dim``, ints kept as ints and every other number
a float. Every problem is a ``SceneError`` with a one-line message of the form

    scene 'foo.toml': grid.cells: expected 2 positive integers, got [10, -1]

naming the scene, the dotted key, the bad value and what was expected. The schema itself (keys,
defaults, allowed values) is documented in ``parmpm.scene.reference``; the tuples below are its vocabulary,
and the names of interpolators, material models and metrics come from their registries
(:mod:`parmpm.shapes`, :mod:`parmpm.materials`, :mod:`parmpm.output.metrics`). No MPI, no numba: reading
and checking a scene compiles nothing.
"""

from __future__ import annotations

import math
import re
from typing import Any

from parmpm.output.metrics import metric_names, separation_kinds
from parmpm.scene.bodies import (  # noqa: F401
    BODY_KEYS,
    SHAPE_DIMS,
    SHAPE_KEYS,
    VIBRATION_KEYS,
    check_bodies,
)
from parmpm.scene.check import AXIS_NAMES, LCR_INTERPOLATORS, Checker, lcr_length, show
from parmpm.scene.history import check_columns, history
from parmpm.scene.contact import check_contact
from parmpm.scene.loads import check_loads, check_walls
from parmpm.scene.materials import DAMAGE_KEYS, MATERIAL_KEYS, check_materials  # noqa: F401
from parmpm.scene.records import Body, Material, build
from parmpm.scene.speed import check_speeds
from parmpm.shapes import INTERPOLATORS
from parmpm.transfer.affine import AFFINE_TRANSFERS, APIC_INTERPOLATORS, TRANSFERS
from parmpm.transfer.update_order import UPDATES as _UPDATE_ORDERS

DIMS = (1, 2, 3)
UPDATES = ("auto", *_UPDATE_ORDERS)  # "auto": USL for cpdi and cpdi2, MUSL for the others
BOUNDARY_KINDS = ("fixed", "slip", "symmetry", "clamped", "free")

TOP_KEYS = ("name", "description", "dim", "grid", "materials", "bodies", "method", "gravity",
            "damping", "boundary", "time", "output", "metrics", "decomposition", "checkpoint",
            "manufactured", "walls", "loads", "contact")
GRID_KEYS = ("origin", "cell_size", "cells", "patch_size", "ghost", "exterior")
#: the widest grid.exterior layer: a support reaches at most the ghost width past a face
MAX_EXTERIOR = 64
METHOD_KEYS = ("interpolator", "lcr", "update", "flip", "transfer")
GRAVITY_KEYS = ("g", "ramp_time")
DAMPING_KEYS = ("coefficient",)
MANUFACTURED_KEYS = ("amplitude",)
TIME_KEYS = ("end", "steps", "cfl", "dt_max", "dt", "max_energy_growth")
#: the most steps a fixed ``time.dt`` may need to reach ``time.end`` (a typo such as 1e-30 for
#: 1e-3 would otherwise start a run that never ends)
MAX_FIXED_STEPS = 10**9
OUTPUT_KEYS = ("every", "every_steps", "snapshots", "figure", "domains", "history")
#: snapshots per run when the scene gives no schedule
OUTPUT_ROWS = 20
METRICS_KEYS = ("kind", "every_steps", "axis", "stop_on_separation", "grip")
DECOMPOSITION_KEYS = ("rebalance_threshold", "rebalance_cooldown")
CHECKPOINT_KEYS = ("every_steps", "every", "wall_minutes", "keep", "at_end", "ranks_per_file")

DEFAULT_PATCH_SIZE = {1: 64, 2: 64, 3: 16}  # measured: parmpm.scene.patch_size
DEFAULT_LCR = "2dx"  # for the interpolators that cap their domains (LCR_INTERPOLATORS)

# ---------------------------------------------------------------- sections


#: a scene name becomes the output folder and file names, so it is kept to a safe set
NAME_RE = re.compile(r"[A-Za-z0-9](?:[A-Za-z0-9_.+ -]{0,98}[A-Za-z0-9_.+-])?")
NAME_EXPECTED = ("1 to 100 letters, digits, spaces, '_', '-', '.' or '+', starting with a "
                 "letter or digit (it names the output files)")
#: grid coordinates must resolve a cell: |origin| and the extent stay below this many cells
MAX_COORDINATE_CELLS = 1e12


def resolve(raw: dict, where: str, default_name: str,
            origins: dict[str, str] | None = None) -> dict:
    """Validate a raw scene dict and return the resolved scene (see module docstring)."""
    c = Checker(where, origins or {})
    c.table("", raw, TOP_KEYS)
    dim = c.integer("dim", c.required("", raw, "dim", "1, 2 or 3"), "1, 2 or 3",
                    lambda d: d in DIMS)
    name = c.string("name", raw.get("name", default_name), NAME_EXPECTED)
    if not NAME_RE.fullmatch(name):  # it names folders and files: no paths, no surprises
        c.expected("name", NAME_EXPECTED, name)
    out: dict[str, Any] = {
        "name": name,
        "description": c.string("description", raw.get("description", "")),
        "dim": dim,
    }
    out["grid"] = _grid(c, raw.get("grid", {}), dim)
    out["materials"] = check_materials(c, raw.get("materials", {}))
    out["bodies"] = check_bodies(c, raw.get("bodies", []), dim, out["grid"], out["materials"])
    check_speeds(c, [build(Body, b) for b in out["bodies"]],  # an energy that overflows
                 {n: build(Material, m) for n, m in out["materials"].items()})
    min_dx = min(out["grid"]["cell_size"])
    # an l_cr past the grid caps nothing, and its ghost width must still be allocated
    max_cells = max(max(out["grid"]["cells"]), MAX_EXTERIOR)
    out["method"] = _method(c, raw.get("method", {}), min_dx, max_cells)
    out["gravity"] = _gravity(c, raw.get("gravity", {}), dim)
    damping = c.table("damping", raw.get("damping", {}), DAMPING_KEYS)
    out["damping"] = {"coefficient": c.number("damping.coefficient",
                                              damping.get("coefficient", 0.0),
                                              "a number >= 0 (1/s)", lambda x: x >= 0)}
    out["boundary"] = _boundary(c, raw.get("boundary", {}), dim)
    _regions_and_splines(c, out["method"]["interpolator"], out["boundary"])
    out["manufactured"] = _manufactured(c, raw.get("manufactured"), out["materials"])
    names: set = set()  # walls and loads name history columns: one namespace
    for section, check in (("walls", lambda r: check_walls(c, r, dim, names)),
                           ("loads", lambda r: check_loads(c, r, dim, out["bodies"], names,
                                                              out["grid"]))):
        if raw.get(section):  # absent when empty: older scenes resolve as they did
            out[section] = check(raw[section])
        elif section in raw and not isinstance(raw[section], list):
            c.expected(section, f"an array of tables [[{section}]]", raw[section])
    if "contact" in raw:  # absent when not given: older scenes resolve as they did
        out["contact"] = check_contact(c, raw["contact"], len(out["bodies"]), out["materials"],
                                       names)
    if out.get("loads") and out["manufactured"]:
        c.fail("loads", "expected no [[loads]] with [manufactured] (its body force is the load)")
    out["time"] = _time(c, raw.get("time", {}))
    out["output"] = _output(c, raw.get("output", {}), out)
    check_columns(c, out)
    out["metrics"] = _metrics(c, raw.get("metrics", {}), dim, out["bodies"])
    out["decomposition"] = _decomposition(c, raw.get("decomposition", {}))
    out["checkpoint"] = _checkpoint(c, raw.get("checkpoint", {}))
    return out


def _regions_and_splines(c: Checker, interpolator: str, boundary: dict) -> None:
    """Held node regions inside the grid and quadratic B-splines do not mix: a B-spline reaches
    1.5 cells, so particles a cell away from the region still lean on its held nodes (a bar held
    by a region vibrates as if held about 0.35 cells further out). A grid face mirrors the
    splines exactly (:mod:`parmpm.grid.symmetry`): the fix the message names. A study that
    measures the error (``tests/shapes/test_bspline.py``) says ``boundary.regions_with_splines``."""
    if interpolator != "bspline" or boundary.get("regions_with_splines"):
        return
    for kind in ("fixed_regions", "slip_regions"):
        if boundary[kind]:
            c.fail(f"boundary.{kind}", "held node regions give B-spline runs wrong answers (a "
                   "spline reaches 1.5 cells, past the region's edge: a bar held by a region "
                   "vibrates as if held about 0.35 cells further out); hold the body at a grid "
                   'face instead (boundary.<x|y|z>_<min|max> = "clamped", or "symmetry" for a '
                   "roller, which B-splines mirror exactly), or use another interpolator "
                   "(boundary.regions_with_splines = true keeps the regions, for a comparison)")


def _decomposition(c: Checker, raw: Any) -> dict:
    dec = c.table("decomposition", raw, DECOMPOSITION_KEYS)
    return {
        "rebalance_threshold": c.number("decomposition.rebalance_threshold",
                                        dec.get("rebalance_threshold", 0.1),
                                        "a number >= 0 (max/mean - 1 of particles per rank)",
                                        lambda x: x >= 0),
        "rebalance_cooldown": c.integer("decomposition.rebalance_cooldown",
                                        dec.get("rebalance_cooldown", 50), "an integer >= 1",
                                        lambda n: n >= 1),
    }


def _checkpoint(c: Checker, raw: Any) -> dict:
    ck = c.table("checkpoint", raw, CHECKPOINT_KEYS)
    return {
        "every_steps": None if ck.get("every_steps") is None else c.integer(
            "checkpoint.every_steps", ck["every_steps"], "an integer >= 1", lambda n: n >= 1),
        "every": None if ck.get("every") is None else c.number(
            "checkpoint.every", ck["every"], "a number > 0 (simulated s)", lambda x: x > 0),
        "wall_minutes": None if ck.get("wall_minutes") is None else c.number(
            "checkpoint.wall_minutes", ck["wall_minutes"], "a number > 0 (minutes)", lambda x: x > 0),
        "keep": c.integer("checkpoint.keep", ck.get("keep", 3), "an integer >= 1", lambda n: n >= 1),
        "at_end": c.boolean("checkpoint.at_end", ck.get("at_end", False)),
        # "auto": one part file per rank up to 256 ranks (parmpm.io.checkpoint_parts)
        "ranks_per_file": ck.get("ranks_per_file", "auto") if ck.get("ranks_per_file", "auto")
        == "auto" else c.integer("checkpoint.ranks_per_file", ck["ranks_per_file"],
                                 '"auto" or an integer >= 1', lambda n: n >= 1),
    }


def _grid(c: Checker, raw: Any, dim: int) -> dict:
    t = c.table("grid", raw, GRID_KEYS)
    cell_size = c.vector("grid.cell_size", c.required("grid", t, "cell_size",
                                                      f"{dim} positive numbers"), dim, "float>0")
    cells = c.vector("grid.cells", c.required("grid", t, "cells", f"{dim} positive integers"),
                     dim, "int>0")
    origin = c.vector("grid.origin", t.get("origin", 0.0), dim, "float")
    # "auto" (default): chosen at set-up from the scene alone, never the rank count
    # (parmpm.scene.patch_size); an explicit size is clipped to the cell count
    patch = t.get("patch_size", "auto")
    if patch != "auto":
        if isinstance(patch, str):
            c.expected("grid.patch_size", f'"auto" or {dim} positive integers (cells per patch '
                       "per axis)", patch)
        patch = [min(p, n) for p, n in zip(c.vector("grid.patch_size", patch, dim, "int>0"),
                                           cells)]
    for k in range(dim):  # node coordinates must stay finite and tell cells apart
        extent = cells[k] * cell_size[k]
        far = max(abs(origin[k]), abs(origin[k] + extent))
        if not math.isfinite(extent) or far > MAX_COORDINATE_CELLS * cell_size[k]:
            c.fail("grid", f"axis {'xyz'[k]}: origin {origin[k]:g} m and {cells[k]} cells of "
                           f"{cell_size[k]:g} m reach {far:g} m, which double precision cannot "
                           f"resolve in cells of that size (keep |coordinates| below "
                           f"{MAX_COORDINATE_CELLS:g} cells)")
    ghost = t.get("ghost", "auto")
    if ghost != "auto":
        c.integer("grid.ghost", ghost, '"auto" or an integer from 1 to the largest cell count '
                  f"({max(cells)})", lambda g: 1 <= g <= max(cells))
    exterior = t.get("exterior", "auto")  # cells kept outside every face (parmpm.step.stepper)
    if exterior != "auto":
        c.integer("grid.exterior", exterior, f'"auto" or an integer from 0 to {MAX_EXTERIOR} '
                  "(cells kept outside every face)", lambda n: 0 <= n <= MAX_EXTERIOR)
    return {"origin": origin, "cell_size": cell_size, "cells": cells,
            "patch_size": patch, "ghost": ghost,
            "exterior": exterior}


def _method(c: Checker, raw: Any, min_dx: float, max_cells: float = math.inf) -> dict:
    """``max_cells``: the longest l_cr in cells (it sets the ghost width)."""
    t = c.table("method", raw, METHOD_KEYS)
    interp = c.choice("method.interpolator", t.get("interpolator", "cpdi"), tuple(INTERPOLATORS))
    lcr = t.get("lcr")
    if lcr is None:
        lcr = DEFAULT_LCR if interp in LCR_INTERPOLATORS else "none"
    try:
        length = lcr_length(lcr, min_dx)
    except ValueError as exc:
        c.expected("method.lcr", str(exc), lcr)
    if length is not None and length > max_cells * min_dx:
        c.fail("method.lcr", f"{show(lcr)} is {length / min_dx:g} cells long, more than the grid "
                             f"spans or a ghost layer may be wide ({max_cells} cells): use "
                             "\"none\" for no cap, or a shorter length")
    if interp not in LCR_INTERPOLATORS and length is not None:
        c.fail("method.lcr", f'only used by interpolators "cpdi" and "cpdi2", got {show(lcr)} with '
                             f'interpolator "{interp}" (leave it out or set it to "none")')
    if not isinstance(lcr, str):
        lcr = float(lcr)
    transfer = c.choice("method.transfer", t.get("transfer", "flip"), TRANSFERS)
    if transfer in AFFINE_TRANSFERS and interp not in APIC_INTERPOLATORS:
        c.fail("method.transfer", f'"{transfer}" needs interpolator "bspline" (its D_p = Δx²/4 '
                                  f'is a constant), got interpolator "{interp}"')
    if transfer in AFFINE_TRANSFERS and "flip" in t:
        c.fail("method.flip", f'{show(t["flip"])} has no meaning with method.transfer = '
                              f'"{transfer}" (its affine transfer replaces the FLIP/PIC blend): '
                              'leave it out')
    out = {
        "interpolator": interp,
        "lcr": lcr,
        "update": c.choice("method.update", t.get("update", "auto"), UPDATES),
        "transfer": transfer,
    }
    if transfer == "flip":  # APIC/MLS have no blend: their resolved scene has no flip key
        out["flip"] = c.number("method.flip", t.get("flip", 1.0), "a number with 0 <= flip <= 1",
                               lambda x: 0 <= x <= 1)
    return out


def _gravity(c: Checker, raw: Any, dim: int) -> dict:
    t = c.table("gravity", raw, GRAVITY_KEYS)
    return {
        "g": c.vector("gravity.g", t.get("g", [0.0] * dim), dim, "float", False),
        "ramp_time": c.number("gravity.ramp_time", t.get("ramp_time", 0.0), "a number >= 0 (s)",
                              lambda x: x >= 0),
    }


def _manufactured(c: Checker, raw: Any, materials: dict) -> dict | None:
    """The manufactured-solution forcing (parmpm.loads.manufactured): neo-Hookean, one material."""
    if raw is None:
        return None
    t = c.table("manufactured", raw, MANUFACTURED_KEYS)
    amplitude = c.number("manufactured.amplitude",
                         c.required("manufactured", t, "amplitude", "a number > 0 (m)"),
                         "a number > 0 (m)", lambda x: x > 0)
    if len(materials) != 1 or next(iter(materials.values()))["model"] != "neo_hookean":
        c.fail("manufactured", "expected exactly one material, of model \"neo_hookean\" (the "
                               "manufactured body force is derived for it), got "
                               + ", ".join(f"{n} ({m['model']})" for n, m in materials.items()))
    return {"amplitude": amplitude}


def _boundary(c: Checker, raw: Any, dim: int) -> dict:
    every = tuple(f"{a}_{side}" for a in AXIS_NAMES for side in ("min", "max"))
    t = c.table("boundary", raw, every + ("fixed_regions", "slip_regions",
                                          "regions_with_splines"))
    out = {}
    if t.get("regions_with_splines") is not None:  # absent unless given: older scenes unchanged
        out["regions_with_splines"] = c.boolean("boundary.regions_with_splines",
                                                t["regions_with_splines"])
    for kind, extra in (("fixed_regions", ()), ("slip_regions", ("normal",))):
        regions = t.get(kind, [])
        what = "{min, max}" if not extra else "{min, max, normal}"
        if not isinstance(regions, list):
            c.expected(f"boundary.{kind}", f"a list of tables {what}", regions)
        out[kind] = []
        for i, reg in enumerate(regions):
            key = f"boundary.{kind}.{i}"
            r = c.table(key, reg, ("min", "max") + extra)
            lo = c.vector(f"{key}.min", c.required(key, r, "min", f"{dim} numbers"), dim, "float", False)
            hi = c.vector(f"{key}.max", c.required(key, r, "max", f"{dim} numbers"), dim, "float", False)
            if any(b < a for a, b in zip(lo, hi)):
                c.fail(f"{key}.max", f"expected max >= min on every axis, got min {show(lo)} max {show(hi)}")
            region = {"min": lo, "max": hi}
            if extra:
                axes = tuple(AXIS_NAMES[:dim])
                region["normal"] = c.choice(f"{key}.normal", c.required(key, r, "normal", " or ".join(
                    f'"{a}"' for a in axes)), axes)
            out[kind].append(region)
    for name in every:
        if AXIS_NAMES.index(name[0]) >= dim:
            if name in t:
                c.fail(f"boundary.{name}", f"no {name[0]} axis in a {dim}D scene (expected keys "
                                           + ", ".join(every[: 2 * dim]) + ")")
            continue
        out[name] = c.choice(f"boundary.{name}", t.get(name, "free"), BOUNDARY_KINDS)
    return out


def _time(c: Checker, raw: Any) -> dict:
    t = c.table("time", raw, TIME_KEYS)
    end, steps = t.get("end"), t.get("steps")
    if end is None and steps is None:
        c.fail("time", "expected time.end (a positive number, s) and/or time.steps "
                       "(a positive integer), got neither")
    cfl = t.get("cfl", 0.4)
    if not isinstance(cfl, bool) and isinstance(cfl, (int, float)) and cfl >= 1:
        c.expected("time.cfl", "a number with 0 < cfl < 1 (the CFL number must be < 1)", cfl)
    dt_max, dt = t.get("dt_max"), t.get("dt")
    if dt is not None and dt_max is not None:
        c.fail("time.dt", f"expected time.dt (a fixed step, s) or time.dt_max (a cap on the CFL "
                          f"step), not both: got dt = {dt!r} and dt_max = {dt_max!r}")
    out = {
        "end": None if end is None else c.number("time.end", end, "a number > 0 (s)",
                                                 lambda x: x > 0),
        "steps": None if steps is None else c.integer("time.steps", steps, "an integer > 0",
                                                      lambda n: n > 0),
        "cfl": c.number("time.cfl", cfl, "a number with 0 < cfl < 1", lambda x: 0 < x < 1),
        "dt_max": None if dt_max is None else c.number("time.dt_max", dt_max,
                                                       "a number > 0 (s)", lambda x: x > 0),
        # a fixed step instead of the CFL one (parmpm.driver.schedule.Clock)
        "dt": None if dt is None else c.number("time.dt", dt, "a number > 0 (s)",
                                               lambda x: x > 0),
        # the blow-up watch (parmpm.output.energy): "off" or the largest growth of the energy balance
        "max_energy_growth": _energy_limit(c, t.get("max_energy_growth", 1.0)),
    }
    fixed, end, steps = out["dt"], out["end"], out["steps"]
    if (fixed is not None and end is not None and end / fixed > MAX_FIXED_STEPS
            and (steps is None or steps > MAX_FIXED_STEPS)):
        c.fail("time.dt", f"time.dt = {fixed!r} s would take {end / fixed:.3g} steps to reach "
                          f"time.end = {end!r} s (more than {MAX_FIXED_STEPS:.0e}): expected a "
                          "larger time.dt, or time.steps to stop it")
    return out


def _energy_limit(c: Checker, value: Any) -> float | str:
    if value == "off":
        return value
    return c.number("time.max_energy_growth", value, 'a number > 0 (a fraction of the energy '
                    'the body was given) or "off"', lambda x: 0 < x < 1e300)


def _output(c: Checker, raw: Any, scene: dict) -> dict:
    t = c.table("output", raw, OUTPUT_KEYS)
    time = scene["time"]
    every, every_steps = c.schedule("output", t, time, OUTPUT_ROWS)
    return {
        "every": every,
        "every_steps": every_steps,
        "snapshots": c.boolean("output.snapshots", t.get("snapshots", True)),
        "figure": c.boolean("output.figure", t.get("figure", True)),
        "domains": c.boolean("output.domains", t.get("domains", True)),
        "history": history(c, t.get("history", {}), time, scene["dim"], scene["bodies"],
                           scene["materials"]),
    }


def _metrics(c: Checker, raw: Any, dim: int, bodies: list) -> dict:
    t = c.table("metrics", raw, METRICS_KEYS)
    kind = c.choice("metrics.kind", t.get("kind", "none"), metric_names())
    axis = t.get("axis")
    if axis is None:
        vibrating = [b["vibration"]["axis"] for b in bodies if b["vibration"] is not None]
        axis = vibrating[0] if kind == "vibrating_bar" and vibrating else dim - 1
    out = {
        "kind": kind,
        "every_steps": c.integer("metrics.every_steps", t.get("every_steps", 1),
                                 "an integer >= 1", lambda n: n >= 1),
        "axis": c.integer("metrics.axis", axis, f"an integer in [0, {dim})",
                          lambda a: 0 <= a < dim),
        "stop_on_separation": c.boolean("metrics.stop_on_separation",
                                        t.get("stop_on_separation", False)),
    }
    if kind == "none":  # no metrics, nothing to stop on (e.g. --set metrics.kind=none)
        out["stop_on_separation"] = False
    separating = separation_kinds()
    if out["stop_on_separation"] and kind not in separating:
        c.fail("metrics.stop_on_separation", "only the " + " and ".join(
            f'"{k}"' for k in separating) + f' metrics track separation, got metrics.kind "{kind}"')
    out["grip"] = None
    if kind == "tension_bar":
        grip = c.string("metrics.grip", t.get("grip", "grip"), "a material name")
        held = [b for b in bodies if b["material"] == grip]
        if len(held) != 2 or any(b["shape"] != "box" for b in held):
            c.fail("metrics.grip", f"expected exactly two box bodies of material {show(grip)} (the "
                                   f"grips at the bar's ends), got {len(held)}"
                                   + (" (not all boxes)" if held and len(held) == 2 else ""))
        if len(held) == len(bodies):
            c.fail("metrics.grip", f"expected a bar between the grips: every body is of material "
                                   f"{show(grip)}")
        out["grip"] = grip
    elif "grip" in t:
        c.fail("metrics.grip", f'used only by metrics.kind "tension_bar", got kind "{kind}"')
    return out
