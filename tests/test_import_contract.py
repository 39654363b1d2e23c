"""The import contract that keeps the layers apart (read from the source, imports inside
functions included):

* ``decomposition/`` is a physics-free leaf: it never imports ``parmpm``;
* the kernels and the formulas they call (transfers, grid update, specialised kernels, shapes,
  materials, kinematics) import no scene module, nothing of ``parmpm.io``, not the particle
  store and nothing of the run (simulation, set-up, callbacks, output files): they see arrays
  and records only;
* the registries (``parmpm.shapes``, ``parmpm.materials``, ``parmpm.metrics``,
  ``parmpm.update_order``) import no compiled module at import time: reading a scene compiles
  nothing (``tests/test_registries.py`` checks the same by importing them).
"""
import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
KERNEL_MODULES = (["parmpm/transfer.py", "parmpm/grid.py", "parmpm/kinematics.py",
                   "parmpm/kernel_records.py", "parmpm/patch_index.py", "parmpm/jit.py",
                   "parmpm/update_order.py"]
                  + [str(p.relative_to(ROOT)) for d in ("kernels2d", "kernels3d", "shapes", "materials")
                     for p in sorted((ROOT / "parmpm" / d).glob("*.py"))])
#: what a kernel module may not import (module prefixes)
KERNEL_FORBIDDEN = ("parmpm.scene", "parmpm.io", "parmpm.particles", "parmpm.seeding",
                    "parmpm.simulation", "parmpm.rank_state", "parmpm.callbacks",
                    "parmpm.run_files", "parmpm.measures", "parmpm.stepper", "parmpm.metrics")
REGISTRIES = ("parmpm/shapes/__init__.py", "parmpm/materials/__init__.py",
              "parmpm/metrics/__init__.py", "parmpm/update_order.py")


def imports(path: Path, top_level_only: bool = False) -> list[str]:
    """Every module ``path`` imports (absolute names; relative imports resolved)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    package = ".".join(path.relative_to(ROOT).with_suffix("").parts[:-1])
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


def _hits(names, prefixes):
    return sorted({n for n in names for p in prefixes if n == p or n.startswith(p + ".")
                   or (n.startswith(p) and p.endswith("scene"))})


@pytest.mark.parametrize("path", sorted(str(p.relative_to(ROOT))
                                        for p in (ROOT / "decomposition").glob("*.py")))
def test_decomposition_never_imports_parmpm(path):
    assert _hits(imports(ROOT / path), ("parmpm",)) == []


@pytest.mark.parametrize("path", KERNEL_MODULES)
def test_kernels_import_no_scene_io_particle_store_or_run(path):
    assert _hits(imports(ROOT / path), KERNEL_FORBIDDEN) == []


@pytest.mark.parametrize("path", REGISTRIES)
def test_registries_import_no_kernel_at_import_time(path):
    compiled = ("numba", "parmpm.jit", "parmpm.transfer", "parmpm.kernels2d", "parmpm.kernels3d",
                "parmpm.shapes.support", "parmpm.materials.laws", "parmpm.kinematics")
    assert _hits(imports(ROOT / path, top_level_only=True), compiled) == []


def test_the_checker_sees_what_it_must():
    """The parser finds relative, nested and aliased imports (so the tests above can fail)."""
    src = ROOT / "tests" / "_contract_probe.py"
    src.write_text("import numba as nb\nfrom . import mpi_launch\n"
                   "def f():\n    from parmpm.particles import Particles\n", encoding="utf-8")
    try:
        names = imports(src)
        assert "numba" in names and "tests.mpi_launch" in names
        assert _hits(names, KERNEL_FORBIDDEN) == ["parmpm.particles", "parmpm.particles.Particles"]
        assert _hits(imports(src, top_level_only=True), ("parmpm",)) == []
    finally:
        src.unlink()
    assert len(KERNEL_MODULES) > 20  # the globs found the packages
