"""The import contract that keeps the layers apart, read from the source (imports inside functions
included), with the allowed arrows derived from the layer order ``parmpm.LAYERS``:

* a module of layer package ``parmpm.<L>`` imports only modules of its own package or of packages
  listed after ``L`` in ``LAYERS`` (below it); nothing imports the package root ``parmpm``;
* there is no import cycle between modules anywhere in ``parmpm/``;
* ``decomposition/`` is a physics-free leaf: it never imports ``parmpm``;
* the physics layers (transfer and below) read and write no files: they import nothing of
  ``parmpm.io``;
* the registries (``parmpm.shapes``, ``parmpm.materials``, ``parmpm.output.metrics``,
  ``parmpm.transfer.update_order``) import no compiled module at import time: reading a scene
  compiles nothing (``tests/scene/test_registries.py`` checks the same by importing them).

The checkers take the tree's root, so the last tests run them on a small tree made for the test
with an arrow pointing up and a cycle, and see both reported.
"""
import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
#: the layers that compute (the kernels and the formulas they call): no files
FILE_FREE = ("transfer", "shapes", "grid", "materials", "geometry", "exact")
REGISTRIES = ("parmpm/shapes/__init__.py", "parmpm/materials/__init__.py",
              "parmpm/output/metrics/__init__.py", "parmpm/transfer/update_order.py")


def layers(root: Path) -> tuple[str, ...]:
    """``LAYERS`` as written in ``parmpm/__init__.py`` (read, not imported)."""
    tree = ast.parse((root / "parmpm" / "__init__.py").read_text(encoding="utf-8"))
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", "") == "LAYERS" for t in node.targets):
            return tuple(ast.literal_eval(node.value))
    raise AssertionError("parmpm/__init__.py defines no LAYERS")


def module_name(root: Path, path: Path) -> str:
    parts = path.relative_to(root).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports(root: Path, path: Path, top_level_only: bool = False) -> list[str]:
    """Every module ``path`` imports (absolute names; relative imports resolved)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    package = ".".join(path.relative_to(root).with_suffix("").parts[:-1])
    nodes = tree.body if top_level_only else ast.walk(tree)
    out = []
    for node in nodes:
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[:len(base) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            out.append(mod)
            out += [f"{mod}.{a.name}" for a in node.names]  # `from parmpm import io`
    return out


def graph(root: Path) -> dict[str, set[str]]:
    """Module -> the parmpm modules it imports (names resolved to the longest existing module)."""
    paths = {module_name(root, p): p for p in sorted((root / "parmpm").rglob("*.py"))}
    out = {}
    for name, path in paths.items():
        targets = set()
        for imported in imports(root, path):
            while imported and imported not in paths:
                imported = imported.rpartition(".")[0]
            if imported and imported != name:
                targets.add(imported)
        out[name] = targets
    return out


def upward_arrows(root: Path) -> list[str]:
    """Every import that points up the layer order, or into the package root."""
    order = layers(root)
    rank = {layer: k for k, layer in enumerate(order)}
    bad = []
    for mod, targets in graph(root).items():
        if mod in ("parmpm", "parmpm.__main__"):
            continue  # the public API and the entry point sit above every layer
        here = mod.split(".")[1]
        assert here in rank, f"{mod} is in no layer of LAYERS {order}"
        for target in sorted(targets):
            there = target.split(".")[1] if "." in target else None
            if there is None or (there != here and rank.get(there, -1) < rank[here]):
                bad.append(f"{mod} -> {target}")
    return bad


def cycles(root: Path) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    g = graph(root)
    index, low, stack, on, found, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in g[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in g:
        if v not in index:
            visit(v)
    return found


def _hits(names, prefixes):
    return sorted({n for n in names for p in prefixes if n == p or n.startswith(p + ".")})


def test_every_arrow_points_down_the_layers():
    assert upward_arrows(ROOT) == []


def test_no_import_cycle():
    assert cycles(ROOT) == []


def test_every_package_is_a_layer():
    """A new folder under parmpm/ must be placed in the order (LAYERS) before it can be used."""
    packages = sorted(p.name for p in (ROOT / "parmpm").iterdir() if (p / "__init__.py").exists())
    assert packages == sorted(layers(ROOT))


@pytest.mark.parametrize("path", sorted(str(p.relative_to(ROOT))
                                        for p in (ROOT / "decomposition").glob("*.py")))
def test_decomposition_never_imports_parmpm(path):
    assert _hits(imports(ROOT, ROOT / path), ("parmpm",)) == []


@pytest.mark.parametrize("layer", FILE_FREE)
def test_physics_layers_read_and_write_no_files(layer):
    for path in sorted((ROOT / "parmpm" / layer).rglob("*.py")):
        assert _hits(imports(ROOT, path), ("parmpm.io", "h5py", "meshio")) == [], path


@pytest.mark.parametrize("path", REGISTRIES)
def test_registries_import_no_kernel_at_import_time(path):
    compiled = ("numba", "parmpm.core.jit", "parmpm.transfer.generic", "parmpm.transfer.kernels2d",
                "parmpm.transfer.kernels3d", "parmpm.shapes.support", "parmpm.materials.laws",
                "parmpm.materials.kinematics")
    assert _hits(imports(ROOT, ROOT / path, top_level_only=True), compiled) == []


def _tree(tmp_path: Path, files: dict[str, str]) -> Path:
    for name, text in {"parmpm/__init__.py": 'LAYERS = ("step", "grid", "core")\n', **files}.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text, encoding="utf-8")
    return tmp_path


def test_an_arrow_pointing_up_is_reported(tmp_path):
    """The checker fails on the arrow it must refuse: ``grid`` (below) importing ``step`` (above),
    lazily inside a function, and a module importing the root; downward arrows pass."""
    root = _tree(tmp_path, {
        "parmpm/step/__init__.py": "", "parmpm/grid/__init__.py": "", "parmpm/core/__init__.py": "",
        "parmpm/step/stepper.py": "from parmpm.grid.update import f\nimport parmpm.core.jit\n",
        "parmpm/grid/update.py": "def f():\n    from parmpm.step.stepper import Stepper\n",
        "parmpm/core/jit.py": "from parmpm import LAYERS\n",
    })
    assert upward_arrows(root) == ["parmpm.core.jit -> parmpm",
                                   "parmpm.grid.update -> parmpm.step.stepper"]


def test_a_cycle_is_reported(tmp_path):
    root = _tree(tmp_path, {
        "parmpm/core/__init__.py": "",
        "parmpm/core/a.py": "from parmpm.core import b\n",
        "parmpm/core/b.py": "def g():\n    from .a import x\n",
        "parmpm/core/c.py": "from parmpm.core.a import x\n",
    })
    assert cycles(root) == [["parmpm.core.a", "parmpm.core.b"]]
    assert upward_arrows(root) == []
