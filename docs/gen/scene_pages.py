"""Generate the scene reference: reference/scene-keys.md and reference/builtin-scenes.md.

Run by mkdocs-gen-files at build time, from the code only:

* the keys of each section: the schema's key tuples (``GRID_KEYS``, ``METHOD_KEYS``, ...);
* what each key means: the "Scene reference" in the scene package's docstrings (read with
  ``ast``), one bullet per section, linked to the API pages where it names a module;
* the defaults: a minimal scene loaded with ``parmpm.load_scene`` and written back resolved,
  as ``parmpm show`` does (reading a scene compiles nothing);
* the built-in scenes: their TOML files, as shipped.

A key the schema accepts but the docstring never names is a warning, which ``mkdocs build
--strict`` turns into a failed build: the reference cannot silently fall behind the schema.
"""

from __future__ import annotations

import ast
import importlib
import logging
import re
import tempfile
import tomllib
from pathlib import Path

import mkdocs_gen_files

import parmpm

log = logging.getLogger("mkdocs.plugins.parmpm.scene_pages")
ROOT = Path(__file__).resolve().parents[2]
SCENE_PACKAGE = ROOT / "parmpm" / "scene"
KEYS_PAGE = "reference/scene-keys.md"
BUILTIN_PAGE = "reference/builtin-scenes.md"

#: the README's minimal scene: every key not in it shows its default
MINIMAL = """\
dim = 2
[grid]
cell_size = 0.1
cells = [20, 32]
[materials.rubber]
model = "neo_hookean"
density = 1050.0
youngs_modulus = 1.0e6
poisson_ratio = 0.3
[[bodies]]
min = [0.5, 0.5]
max = [1.5, 1.5]
material = "rubber"
[time]
end = 0.1
"""

#: (section title as the docstring's bullet starts, dotted path into the resolved minimal
#: scene, module of the key tuple, the tuple's name)
SECTIONS = (
    ("top level", "", "schema", "TOP_KEYS"),
    ("[grid]", "grid", "schema", "GRID_KEYS"),
    ("[materials.NAME]", "materials.rubber", "schema", "MATERIAL_KEYS"),
    ("[materials.NAME.damage]", None, "schema", "DAMAGE_KEYS"),
    ("[[bodies]]", "bodies.0", "bodies", "BODY_KEYS"),
    ("[bodies.vibration]", None, "bodies", "VIBRATION_KEYS"),
    ("[method]", "method", "schema", "METHOD_KEYS"),
    ("[gravity]", "gravity", "schema", "GRAVITY_KEYS"),
    ("[damping]", "damping", "schema", "DAMPING_KEYS"),
    ("[boundary]", "boundary", None, None),
    ("[manufactured]", None, "schema", "MANUFACTURED_KEYS"),
    ("[time]", "time", "schema", "TIME_KEYS"),
    ("[output]", "output", "schema", "OUTPUT_KEYS"),
    ("[output.history]", "output.history", "history", "HISTORY_KEYS"),
    ("[[output.history.probes]]", None, "history", "PROBE_KEYS"),
    ("[metrics]", "metrics", "schema", "METRICS_KEYS"),
    ("[decomposition]", "decomposition", "schema", "DECOMPOSITION_KEYS"),
    ("[checkpoint]", "checkpoint", "schema", "CHECKPOINT_KEYS"),
    ("[[walls]]", None, "loads", "WALL_KEYS"),
    ("[[loads]]", None, "loads", "LOAD_KEYS"),
    ("time function", None, "loads", "TIME_FUNCTION_KEYS"),
    ("[contact]", None, "contact", "CONTACT_KEYS"),
)
#: where a section's prose lives when it is part of another section's bullet
PROSE_OF = {"[materials.NAME.damage]": "[materials.NAME]", "[bodies.vibration]": "[[bodies]]",
            "time function": "[[loads]]",
            "[output.history]": "[output]", "[[output.history.probes]]": "[output]"}
#: what the docstring does not say about a key, written here (keep it short; better: add it to
#: the docstring, which the code's readers see too)
HAND_WRITTEN = {
    ("[output.history]", "enabled"): "bool, default true; `output.history = false` is short for "
                                     "`enabled = false`: no history file, no per-step ledger",
    ("[[output.history.probes]]", "name"): "required: names the probe's columns "
                                           "(`tip.u.y`); letters, digits, `_`, `-`",
    ("[[output.history.probes]]", "point"): "the particle that started nearest this point "
                                            "(exactly one of point, region, body, material)",
    ("[[output.history.probes]]", "region"): "`{min = [...], max = [...]}`: the particles that "
                                             "started in this box",
    ("[[output.history.probes]]", "body"): "an index into `[[bodies]]`: that body's particles",
    ("[[output.history.probes]]", "material"): "a material's name: its particles",
    ("[[output.history.probes]]", "field"): "one field name (below); or `fields`",
    ("[[output.history.probes]]", "fields"): "a list of field names (below)",
    ("[[output.history.probes]]", "stats"): "region, body and material probes: a list of "
                                            "`\"mean\"` (mass-weighted), `\"min\"`, `\"max\"`; "
                                            "default all three",
}
#: boundary keys are made per axis, not listed in a tuple
BOUNDARY_KEYS = ("x_min", "x_max", "y_min", "y_max", "z_min", "z_max", "fixed_regions",
                 "slip_regions", "regions_with_splines")


def reference_docstring() -> tuple[str, str]:
    """The module of ``parmpm/scene/`` whose docstring holds the scene reference, and the text."""
    for path in sorted(SCENE_PACKAGE.glob("*.py")):
        doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or ""
        if "Scene reference" in doc:
            return "parmpm.scene." + path.stem if path.stem != "__init__" else "parmpm.scene", doc
    raise RuntimeError("no module in parmpm/scene/ has the 'Scene reference' docstring")


def bullets(doc: str) -> dict[str, str]:
    """The reference's bullets by section: ``{"[grid]": "``origin`` (default 0), ...", ...}``."""
    text = doc.split("Scene reference", 1)[1]
    out, current = {}, None
    for line in text.splitlines():
        if line.startswith("* "):
            m = re.match(r"\* ``(.+?)``(.*?):\s(.*)", line) or re.match(r"\* ()(.*?):\s(.*)", line)
            title, note, rest = m.groups()
            current = title or note.strip()
            out[current] = (f"{note.strip()}: " if title and note.strip() else "") + rest.strip()
        elif current and line.startswith("  ") and line.strip():
            out[current] += " " + line.strip()
        elif current and not line.strip():
            current = None
    return out


def defined(dotted: str) -> bool:
    """Whether ``dotted`` names a module, or a public name defined at a module's top level."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        base = ROOT.joinpath(*parts[:cut])
        path = base / "__init__.py" if base.is_dir() else base.with_suffix(".py")
        if path.is_file():
            rest = parts[cut:]
            if not rest:
                return True
            if len(rest) > 1 or rest[0].startswith("_"):
                return False
            tree = ast.parse(path.read_text(encoding="utf-8"))
            names = {n.name for n in tree.body if isinstance(n, (ast.FunctionDef, ast.ClassDef))}
            names |= {t.id for n in tree.body if isinstance(n, (ast.Assign, ast.AnnAssign))
                      for t in (n.targets if isinstance(n, ast.Assign) else [n.target])
                      if isinstance(t, ast.Name)}
            return rest[0] in names
    return False


def _role(match: re.Match) -> str:
    target = match.group(1)
    if defined(target):
        return f"[`{target}`][{target}]"
    log.info("scene reference: %s names %s, which is not defined (left as code)", "docstring",
             target)
    return f"`{target}`"


def markdown(rst: str) -> str:
    """The docstring's reST inline markup as Markdown; a role naming a module or a function links
    to its API page (a stale name stays code: the API pages' anchors decide what can be linked)."""
    text = re.sub(r":(?:mod|func|class|data|meth|attr):`~?([\w.]+)`", _role, rst)
    # outside code, <k> is text, not an HTML tag
    parts = re.split(r"(``.+?``|\[`[\w.]+`\]\[[\w.]+\]|`[^`]+`)", text)
    parts = [p if i % 2 else p.replace("<", "&lt;").replace(">", "&gt;")
             for i, p in enumerate(parts)]
    return re.sub(r"``(.+?)``", r"`\1`", "".join(parts))


def documented(section_text: str, title: str, key: str) -> bool:
    """Whether the bullet names the key (``key``, ``key = ...``, ``[section.key]``, ``section.key``,
    or a per-axis face within ``x_min`` ... ``z_max``)."""
    section = title.strip("[]").replace("NAME.", "")
    forms = (f"``{key}``", f"``{key} =", f"``[{section}.{key}]``", f"``{section}.{key}")
    if re.fullmatch(r"[xyz]_(min|max)", key) and "``x_min`` ... ``z_max``" in section_text:
        return True
    return any(form in section_text for form in forms)


def key_prose(section_text: str, key: str) -> str:
    """What the bullet says about one key: the parenthesis after its name, or ""."""
    if re.fullmatch(r"[xyz]_(min|max)", key):
        key = "z_max"  # the faces share one description: ``x_min`` ... ``z_max`` for ...
    m = re.search(r"``" + re.escape(key) + r"``", section_text)
    if not m:
        return ""
    rest = section_text[m.end():].lstrip()
    if rest.startswith("for "):  # "``x_min`` ... ``z_max`` for the scene's axes only: ..."
        return re.split(r"``|\. |; ", rest, maxsplit=1)[0].strip(" ;,:")
    if not rest.startswith("("):
        return ""
    depth = 0
    for i, ch in enumerate(rest):
        depth += ch == "("
        depth -= ch == ")"
        if depth == 0:
            return rest[1:i]
    return rest[1:]


def resolved_minimal() -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "minimal.toml"
        path.write_text(MINIMAL, encoding="utf-8")
        return tomllib.loads(parmpm.load_scene(path).to_toml())


def lookup(data: dict, dotted: str):
    for part in filter(None, dotted.split(".")):
        data = data[int(part)] if isinstance(data, list) else data.get(part, {})
    return data


def toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, list):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "(table)"
    return repr(value)


def default_cell(table, key: str, prose: str, minimal: dict) -> str:
    if isinstance(table, dict) and isinstance(table.get(key), dict):
        return "a table (below)"
    if isinstance(table, dict) and isinstance(table.get(key), list) and table[key] \
            and isinstance(table[key][0], dict):
        return "an array of tables (below)"
    if key in minimal:
        return "required" if "required" in prose else f"`{toml_value(table[key])}` (example)"
    if table is None:
        return ""
    if key not in table:
        return "(3D only)" if re.fullmatch(r"z_(min|max)", key) else "none"
    return f"`{toml_value(table[key])}`"


def anchor(title: str) -> str:
    """``[materials.NAME.damage]`` -> ``materials-damage``: the section's id on the page."""
    return title.strip("[]").replace(".NAME", "").replace(".", "-").replace(" ", "-")


def cell(text: str) -> str:
    return " ".join(markdown(text).split()).replace("|", "\\|")


def section_keys(module: str | None, name: str | None) -> tuple[str, ...]:
    """A section's key tuple: from the module named, else from whichever scene module defines
    it (found with ``ast``, so a tuple moved within the package is still found)."""
    if module is None:
        return BOUNDARY_KEYS
    candidates = [f"parmpm.scene.{module}"] + [
        f"parmpm.scene.{p.stem}" for p in sorted(SCENE_PACKAGE.glob("*.py"))
        if re.search(rf"^{name}\b\s*[:=]", p.read_text(encoding="utf-8"), re.M)]
    for candidate in candidates:
        try:
            keys = getattr(importlib.import_module(candidate), name)
        except (ImportError, AttributeError):
            continue
        return tuple(keys)
    log.warning("scene reference: no module of parmpm.scene defines %s", name)
    return ()


def keys_page() -> str:
    source, doc = reference_docstring()
    prose = bullets(doc)
    resolved = resolved_minimal()
    raw = tomllib.loads(MINIMAL)
    lines = [
        "# Scene keys",
        "",
        "<!-- generated by docs/gen/scene_pages.py from the scene schema: do not edit -->",
        "",
        "Every key a scene file may hold, section by section, generated at build time from the "
        f"schema's key tuples and the scene reference in [`{source}`][{source}]. "
        "The default column is the value the key takes in the minimal scene below when it is "
        "left out (`parmpm show minimal.toml` prints the same); \"none\" means no value, and "
        "a key whose value depends on others (`output.every`, `metrics.axis`) shows what it "
        "resolved to here. [Writing a scene](scenes.md) explains the ideas; the "
        "[built-in scenes](builtin-scenes.md) are complete examples.",
        "",
        "Per-axis quantities take one number (broadcast to every axis) or a list of `dim` "
        "values; points and vectors (`min`, `max`, `center`, `velocity`, `g`) take a list of "
        "`dim` numbers, or a number in 1D. Every key is checked when the scene is read: a bad "
        "one is a one-line error naming the file, the key, the value and what was expected.",
        "",
        "```toml",
        MINIMAL.rstrip(),
        "```",
        "",
    ]
    for title, path, module, name in SECTIONS:
        keys = section_keys(module, name)
        text = prose.get(title) or prose.get(PROSE_OF.get(title, ""), "")
        if not text:
            log.warning("scene reference: no docstring bullet for section %s in %s", title, source)
        table = lookup(resolved, path) if path is not None else None
        minimal = lookup(raw, path) if path is not None else {}
        heading = "Top level" if title == "top level" else f"`{title}`"
        lines += [f"## {heading} {{#{anchor(title)}}}", ""]
        if title not in PROSE_OF:
            lines += [markdown(text), ""]
        lines += ["| key | default | documented as |", "|---|---|---|"]
        for key in keys:
            if title == "top level" and any(key == (p or "").split(".")[0] for _, p, _, _
                                            in SECTIONS[1:]) or key == "manufactured":
                lines.append(f"| `{key}` | a table | [`[{key}]`](#{key}) |")
                continue
            about = HAND_WRITTEN.get((title, key)) or key_prose(text, key)
            if (title, key) not in HAND_WRITTEN and not documented(text, title, key):
                log.warning("scene reference: %s key '%s' is accepted by the schema but not "
                            "documented in %s", title, key, source)
            table_value = table if isinstance(table, dict) else None
            minimal_table = minimal if isinstance(minimal, dict) else {}
            lines.append(f"| `{key}` | {default_cell(table_value, key, about, minimal_table)} "
                         f"| {cell(about)} |")
        lines.append("")
        if title == "[[output.history.probes]]":
            lines += probe_fields()
    return "\n".join(lines)


def probe_fields() -> list[str]:
    """The fields a probe can read, from the schema's own table (``PROBE_FIELDS``)."""
    fields = getattr(importlib.import_module("parmpm.scene.history"), "PROBE_FIELDS", None)
    if fields is None:
        log.warning("scene reference: parmpm.scene.history.PROBE_FIELDS is gone")
        return []
    kinds = {"": "scalar", "v": "vector: `.x`, `.y`, `.z`", "t": "tensor: `.xx`, `.xy`, ..."}
    lines = ["Probe fields:", "", "| field | what | components |", "|---|---|---|"]
    lines += [f"| `{n}` | {cell(about)} | {kinds.get(k, k)} |" for n, (k, about) in fields.items()]
    return lines + [""]


def builtin_page() -> str:
    scenes = parmpm.builtin_scenes()
    folder = ROOT / "parmpm" / "scene" / "builtin"
    lines = [
        "# Built-in scenes",
        "",
        "<!-- generated by docs/gen/scene_pages.py from parmpm/scene/builtin/: do not edit -->",
        "",
        "The scenes shipped with parmpm, as their TOML files are (`parmpm scenes` lists them, "
        "`parmpm show NAME` prints one resolved, with every default filled in). Run one with "
        "`mpirun -n 2 .venv/bin/python -m parmpm run NAME`.",
        "",
        "| scene | description |",
        "|---|---|",
    ]
    lines += [f"| [`{n}`](#{n}) | {cell(d)} |" for n, d in scenes.items()]
    lines.append("")
    for name in scenes:
        text = (folder / f"{name}.toml").read_text(encoding="utf-8")
        lines += [f"## `{name}` {{#{name}}}", "", "```toml", text.rstrip(), "```", ""]
    return "\n".join(lines)


with mkdocs_gen_files.open(KEYS_PAGE, "w") as f:
    f.write(keys_page())
mkdocs_gen_files.set_edit_path(KEYS_PAGE, "docs/gen/scene_pages.py")
with mkdocs_gen_files.open(BUILTIN_PAGE, "w") as f:
    f.write(builtin_page())
mkdocs_gen_files.set_edit_path(BUILTIN_PAGE, "docs/gen/scene_pages.py")
