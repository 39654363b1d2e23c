"""Scenes: load a TOML scene (built-in or file), apply ``--set`` overrides, validate, resolve.

Configuration is layered: defaults in code (``parmpm.scene.schema``), then the scene TOML, then
the command line (``--set a.b=c``); the result is validated once, at load time, and the resolved
scene (``Scene.to_toml()``) is what checkpoints and summaries store. No MPI, no per-rank arrays.

    scene = load_scene("hanging_bar", overrides=["method.interpolator=mpm", "time.end=0.1"])
    scene.spec.grid.cells           # (20, 30): the typed, frozen records everything reads
    scene.data["grid"]["cells"]     # [20, 30]: the same, serialised (scene.toml, checkpoints)
    scene.lcr                       # resolved CPDI l_cr in metres, or None

The keys, their defaults and what each means: :mod:`parmpm.scene.reference` (the scene
reference the manual's key pages are generated from).
"""

from __future__ import annotations

import os
import re
import sys
import tomllib
from collections.abc import Iterable
from importlib import resources
from pathlib import Path
from typing import Any

from parmpm.core.errors import SceneError
from parmpm.scene.check import lcr_length, one_line, short_text, show, toml_key, toml_value
from parmpm.scene.records import SceneSpec
from parmpm.scene.schema import resolve

__all__ = ["Scene", "load_scene", "scene_from_toml", "builtin_scenes", "parse_lcr",
           "read_scene_text", "scene_identity"]

_SECTION_ORDER = ("grid", "materials", "bodies", "method", "gravity", "damping", "boundary",
                  "manufactured", "time", "output", "metrics", "decomposition", "checkpoint")


class Scene:
    """A validated, fully resolved scene.

    ``spec`` is what a run reads: the scene as typed, frozen records
    (:class:`parmpm.scene.records.SceneSpec`). ``data`` is its serialised form, a plain nested
    dict (every default filled in) that :meth:`to_toml` writes, checkpoints store and the ranks
    compare; ``source`` is the path it was read from or ``"builtin:NAME"``.
    """

    def __init__(self, data: dict, source: str):
        self.data = data
        self.spec = SceneSpec.from_resolved(data)
        self.source = source
        #: a restart's record (:func:`parmpm.driver.restart_keys.check_restart`): the checkpoint, its
        #: step and time, and the keys ``--set`` changed ({key: [stored, new]}); None otherwise
        self.restart: dict | None = None

    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def dim(self) -> int:
        return self.spec.dim

    @property
    def min_dx(self) -> float:
        """Smallest grid spacing, min_k Δx_k."""
        return self.spec.min_dx

    @property
    def lcr(self) -> float | None:
        """CPDI domain-scaling length l_cr in metres; None unless cpdi or cpdi2 with scaling."""
        return self.spec.lcr

    def to_toml(self) -> str:
        """The resolved scene as TOML text; ``scene_from_toml`` on it gives back ``data``."""
        lines = [f"# parmpm scene, resolved from {one_line(self.source)}"]
        if self.restart:  # what ran: the stored scene continued, with these changes
            r = self.restart
            lines.append(f"# a restart: continues from step {r['step']} (t = {r['time']!r} s) "
                         "of that checkpoint's run")
            for key, (was, now) in r["changed"].items():
                lines.append(f"# changed on restart: {key} = {toml_value(now)} (was "
                             f"{toml_value(was)})")
        _emit_table(lines, [], {k: v for k, v in self.data.items() if k not in _SECTION_ORDER})
        for section in _SECTION_ORDER:
            if section in self.data:
                _emit_table(lines, [], {section: self.data[section]})
        return "\n".join(lines).strip() + "\n"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Scene) and self.data == other.data

    def __repr__(self) -> str:
        return f"Scene(name={self.name!r}, dim={self.dim}, source={self.source!r})"


# ---------------------------------------------------------------- TOML emitter


def _is_table_array(value: Any) -> bool:
    return isinstance(value, list) and bool(value) and all(isinstance(v, dict) for v in value)


def _emit_table(lines: list[str], path: list[str], table: dict) -> None:
    """Append ``table`` as TOML: plain keys first, then [sub.tables] and [[arrays.of.tables]].

    ``None`` values are left out (TOML has no null; the schema resolves them back to None).
    """
    for key, value in table.items():
        if value is None or isinstance(value, dict) or _is_table_array(value):
            continue
        lines.append(f"{toml_key(str(key))} = {toml_value(value)}")
    for key, value in table.items():
        sub = path + [toml_key(str(key))]
        if isinstance(value, dict):
            only_tables = value and all(isinstance(v, dict) or _is_table_array(v) or v is None
                                        for v in value.values())
            if not only_tables:  # [materials] needs no header of its own before [materials.bar]
                lines.extend(["", f"[{'.'.join(sub)}]"])
            _emit_table(lines, sub, value)
        elif _is_table_array(value):
            for item in value:
                lines.extend(["", f"[[{'.'.join(sub)}]]"])
                _emit_table(lines, sub, item)


# ---------------------------------------------------------------- loading


def _scenes_dir():
    return resources.files("parmpm.scene") / "builtin"


def builtin_scenes() -> dict[str, str]:
    """Built-in scene name -> its one-line description, sorted by name."""
    out = {}
    for entry in _scenes_dir().iterdir():
        if entry.name.endswith(".toml"):
            name = entry.name[: -len(".toml")]
            try:
                description = tomllib.loads(entry.read_text(encoding="utf-8")).get("description")
            except tomllib.TOMLDecodeError:
                description = None
            out[name] = one_line(str(description or ""))
    return dict(sorted(out.items()))


#: a scene file is a page of TOML; anything this large is not one (and would be read whole)
MAX_SCENE_BYTES = 1 << 20


def load_scene(source: str | Path, overrides: Iterable[str] = ()) -> Scene:
    """Load a scene: a built-in name (``"hanging_bar"``) or a path to a ``.toml`` file.

    ``overrides`` are ``"dotted.key=value"`` strings (the CLI's ``--set``) applied on top of the
    file before validation. Any problem raises a one-line ``SceneError``.
    """
    body, label, default_name = read_scene_text(source)
    return scene_from_toml(body, label, overrides, default_name=default_name)


def scene_identity(source: str | Path) -> str:
    """What ``source`` names, without reading it: ``"builtin:NAME"`` or the file's absolute path
    (two ranks given the same identity read the same file: :mod:`parmpm.scene.agreement`)."""
    text = str(source)
    is_path = isinstance(source, Path) or text.endswith(".toml") or "/" in text or "\\" in text
    if not is_path and text in builtin_scenes():
        return f"builtin:{text}"
    return os.path.abspath(text)


def read_scene_text(source: str | Path) -> tuple[str, str, str]:
    """(TOML text, source label, default name) of a built-in name or a scene file; a file that
    cannot be read is a one-line ``SceneError``. A UTF-8 byte order mark is dropped."""
    text = str(source)
    is_path = isinstance(source, Path) or text.endswith(".toml") or "/" in text or "\\" in text
    if not is_path and text in builtin_scenes():
        body = (_scenes_dir() / f"{text}.toml").read_text(encoding="utf-8")
        return body, f"builtin:{text}", text
    path = Path(text)
    if not is_path and not path.is_file():
        raise SceneError(one_line(
            f"scene '{text}': not a file and not a built-in scene (built-ins: "
            + ", ".join(builtin_scenes()) + ")"))
    if path.exists() and not path.is_file():  # a FIFO or device would block or never end
        raise SceneError(one_line(f"scene '{text}': not a regular file"))
    try:
        if path.stat().st_size > MAX_SCENE_BYTES:
            raise SceneError(one_line(f"scene '{text}': {path.stat().st_size} bytes; a scene "
                                      f"file is at most {MAX_SCENE_BYTES} bytes"))
        body = path.read_text(encoding="utf-8-sig")  # an editor's byte order mark is no error
    except (OSError, UnicodeDecodeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise SceneError(one_line(f"scene '{text}': cannot read file: {reason}")) from None
    return body, text, path.stem


def scene_from_toml(text: str, source: str = "<string>", overrides: Iterable[str] = (),
                    default_name: str | None = None) -> Scene:
    """Build a scene from TOML text (e.g. the scene stored in a checkpoint).

    ``source`` names it in error messages and in ``Scene.source``.
    """
    where = f"scene '{source}'"
    try:
        raw = tomllib.loads(text.removeprefix(BOM))
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(one_line(f"{where}: TOML syntax error: {exc}")) from None
    except ValueError as exc:  # Python's limit on the digits of an integer (4300 by default)
        raise SceneError(f"{where}: {huge_integer(exc)}") from None
    except RecursionError:
        raise SceneError(f"{where}: TOML nested too deeply (arrays or tables within each other "
                         "hundreds of levels deep)") from None
    origins = apply_overrides(raw, overrides, where)
    if default_name is None:
        default_name = source.removeprefix("builtin:")
    data = resolve(raw, where, default_name, origins)
    return Scene(data, source)


# ---------------------------------------------------------------- --set overrides


BOM = "\ufeff"


def huge_integer(exc: ValueError) -> str:
    """The one line for an integer literal past Python's int-string conversion limit."""
    digits = re.search(r"value has (\d+) digits", str(exc))
    return (f"an integer of {digits[1] + ' ' if digits else 'too many '}digits; Python reads at "
            f"most {sys.get_int_max_str_digits() or 'unlimited'} and no scene value needs "
            "more than a few (write a float, e.g. 1e300, if a huge number is meant)")


def parse_override_value(text: str) -> Any:
    """A ``--set`` value: a TOML value (``3``, ``0.1``, ``[0, -9.81]``, ``true``, ``"s"``) or,
    if it does not parse as one, the plain string (``mpm``, ``2dx``). An integer past Python's
    digit limit raises ``ValueError``."""
    try:
        parsed = tomllib.loads("v = " + text)
    except tomllib.TOMLDecodeError:
        return text.strip()
    return parsed["v"] if set(parsed) == {"v"} else text.strip()


def apply_overrides(raw: dict, overrides: Iterable[str], where: str) -> dict[str, str]:
    """Apply ``"a.b.c=value"`` strings to ``raw`` in place; integer parts index arrays
    (``bodies.0.ppc=3``). Returns {normalised dotted key: override text} for error messages."""
    if isinstance(overrides, str):
        overrides = [overrides]
    origins = {}
    for item in overrides:
        text = str(item)
        said = short_text(text)  # as an error message quotes it
        key, sep, value = text.partition("=")
        parts = [p.strip() for p in key.strip().split(".")]
        if not sep or not all(parts):
            raise SceneError(one_line(
                f"{where}: --set {said!r}: expected KEY=VALUE with a dotted KEY "
                "(e.g. method.interpolator=mpm)"))
        node: Any = raw
        for depth, part in enumerate(parts):
            last = depth == len(parts) - 1
            here = ".".join(parts[:depth]) or "the scene"
            if isinstance(node, list):
                if not part.isdigit() or len(part) > 18 or int(part) >= len(node):
                    raise SceneError(one_line(
                        f"{where}: --set {said}: {here} has {len(node)} entries, expected an "
                        f"index 0..{len(node) - 1}, got {short_text(part)!r}"))
                part = int(part)
            elif not isinstance(node, dict):
                raise SceneError(one_line(
                    f"{where}: --set {said}: {here} is {show(node)}, not a table"))
            if last:
                try:
                    node[part] = parse_override_value(value)
                except ValueError as exc:
                    raise SceneError(f"{where}: --set {said}: {huge_integer(exc)}") from None
            else:
                if isinstance(node, dict) and node.get(part) is None:
                    node[part] = {}
                node = node[part]
        # the latest --set of a key goes last: an error blames the one that took effect
        origins.pop(".".join(parts), None)
        origins[".".join(parts)] = text.strip()
    return origins


def parse_lcr(spec: Any, min_dx: float) -> float | None:
    """CPDI critical length l_cr in metres from a spec: ``"2dx"`` -> 2·min_dx,
    ``"1.8dx/3"`` -> 0.6·min_dx, ``"dx"`` -> min_dx, ``0.25`` -> 0.25, ``"none"`` -> None."""
    try:
        return lcr_length(spec, min_dx)
    except ValueError as exc:
        raise SceneError(one_line(f"method.lcr: expected {exc}, got {toml_value(spec)}")) from None
