"""The packages the API reference documents, found by walking the source tree (no imports).

Shared by ``api_pages.py`` (the pages) and ``hooks.py`` (their place in the navigation), so the
reference follows the package layout as it is, not a list kept by hand.
"""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
#: the top-level packages documented, in this order
TOP = ("parmpm", "decomposition")


def layers() -> tuple[str, ...]:
    """``parmpm.LAYERS`` (top to bottom), read from ``parmpm/__init__.py`` without importing it."""
    tree = ast.parse((ROOT / "parmpm" / "__init__.py").read_text(encoding="utf-8"))
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", "") == "LAYERS"
                                                for t in node.targets):
            return tuple(ast.literal_eval(node.value))
    return ()


def packages() -> list[str]:
    """Dotted names of every package (a folder with ``__init__.py``) under :data:`TOP`: the root
    first, then its layers top to bottom as ``parmpm.LAYERS`` lists them (any other package
    after them, by name), each followed by its subpackages."""
    order = {name: i for i, name in enumerate(layers())}
    found = []
    for t, top in enumerate(TOP):
        for init in (ROOT / top).rglob("__init__.py"):
            parts = init.parent.relative_to(ROOT).parts
            if "__pycache__" not in parts:
                layer = order.get(parts[1], len(order)) if len(parts) > 1 else -1
                found.append(((t, layer, parts), ".".join(parts)))
    return [name for _, name in sorted(found)]


def modules(package: str) -> list[str]:
    """The package's own modules (not subpackages), sorted, ``__init__`` left out."""
    folder = ROOT.joinpath(*package.split("."))
    return [f"{package}.{p.stem}" for p in sorted(folder.glob("*.py")) if p.stem != "__init__"]


def summary(dotted: str) -> str:
    """First line of a module's or package's docstring, read with ``ast`` (nothing imported)."""
    path = ROOT.joinpath(*dotted.split("."))
    path = path / "__init__.py" if path.is_dir() else path.with_suffix(".py")
    doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or ""
    return " ".join(doc.split("\n\n")[0].split())


def page_path(package: str) -> str:
    return f"api/{package}.md"
