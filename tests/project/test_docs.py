"""The documentation: its examples run, its scenes load, and a broken cross-reference fails the build.

* Every ```python block in README.md and docs/ preceded by a ``<!-- run -->`` line runs in a fresh
  interpreter (cwd: a temporary folder) and must exit 0; the blocks are small on purpose (a few
  steps of a 1D scene), and unmarked blocks are fragments (a path that needs a run folder).
* Every ```toml block that is a whole scene (it has ``dim``) loads with ``parmpm.load_scene``:
  validation only, nothing runs. Fragments (a ``[materials.NAME.damage]`` table) are skipped.
* The site builds with ``mkdocs build --strict`` as it is, and the same docs with one link to a
  missing page and one to a missing anchor fail, naming both (marker ``docs``; skipped where the
  docs extra is not installed).
"""
from __future__ import annotations

import ast
import importlib.util
import os
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

import parmpm

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
PAGES = sorted([ROOT / "README.md", *DOCS.rglob("*.md")])
BLOCK = re.compile(r"(?P<mark><!-- run -->\n)?```(?P<lang>\w+)\n(?P<body>.*?)\n```", re.S)
MKDOCS_ENV = {"NO_MKDOCS_2_WARNING": "1", "DISABLE_MKDOCS_2_WARNING": "true"}


def blocks(lang: str) -> list:
    out = []
    for page in PAGES:
        text = page.read_text(encoding="utf-8")
        for m in BLOCK.finditer(text):
            if m.group("lang") == lang:
                line = text.count("\n", 0, m.start("body"))
                out.append(pytest.param(m.group("body"), bool(m.group("mark")),
                                        id=f"{page.relative_to(ROOT)}:{line}"))
    return out


RUNNABLE = [p for p in blocks("python") if p.values[1]]
SCENES = [p for p in blocks("toml") if "dim" in tomllib.loads(p.values[0])]


def test_methods_page_shows_the_registry():
    from parmpm.shapes import interpolator_table

    page = (DOCS / "concepts" / "methods.md").read_text(encoding="utf-8")
    assert interpolator_table() in page


#: a repository path in code: parmpm/scene/schema.py, run_scripts/slurm/, tests/test_x.py
PATH_IN_CODE = re.compile(r"`((?:parmpm|decomposition|run_scripts|tests)/[\w./-]*?)`")
#: a dotted name of the code: parmpm.scene.schema, parmpm.shapes.INTERPOLATORS
DOTTED_IN_CODE = re.compile(r"`((?:parmpm|decomposition)(?:\.\w+)+)(?:\(\))?`")


def _defined(dotted: str) -> bool:
    """A module, or a name assigned or defined at the top level of one (read, not imported)."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        base = ROOT.joinpath(*parts[:cut])
        path = base / "__init__.py" if base.is_dir() else base.with_suffix(".py")
        if path.is_file():
            rest = parts[cut:]
            if not rest:
                return True
            tree = ast.parse(path.read_text(encoding="utf-8"))
            names = set()
            for node in ast.walk(tree):
                if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
                    names.add(node.name)
                elif isinstance(node, (ast.Assign, ast.AnnAssign)):
                    targets = node.targets if isinstance(node, ast.Assign) else [node.target]
                    names |= {t.id for t in targets if isinstance(t, ast.Name)}
                elif isinstance(node, ast.ImportFrom):
                    names |= {a.asname or a.name for a in node.names}
            return rest[0] in names
    return False


def test_the_code_the_docs_name_exists():
    """A file, folder or dotted name the pages show in code exists: a move or a rename that
    leaves the manual behind fails here, naming the page and the stale name."""
    stale = []
    for page in PAGES:
        text = page.read_text(encoding="utf-8")
        for m in PATH_IN_CODE.finditer(text):
            path = m.group(1).split("::")[0]
            if "<" not in path and "*" not in path and not (ROOT / path).exists():
                stale.append(f"{page.relative_to(ROOT)}: {path}")
        for m in DOTTED_IN_CODE.finditer(text):
            if not _defined(m.group(1)):
                stale.append(f"{page.relative_to(ROOT)}: {m.group(1)}")
    assert not stale, "\n".join(stale)


def test_readme_links_resolve():
    """The README is read on a forge, not in the site: its relative links must name real files."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    links = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text)
    assert links
    assert [link for link in links if "://" not in link and not (ROOT / link).exists()] == []


def test_the_architecture_page_names_files_that_exist():
    """Each layer's paragraph (``**grid** — ...``) names its files relative to its package."""
    text = (DOCS / "architecture.md").read_text(encoding="utf-8")
    stale = []
    for layer, body in re.findall(r"^\*\*(\w+)\*\* —(.*?)(?=\n\n)", text, re.S | re.M):
        base = ROOT / "decomposition" if layer == "decomposition" else ROOT / "parmpm" / layer
        assert base.is_dir(), f"architecture.md: no package for layer {layer}"
        for name in re.findall(r"`([\w/]+(?:\.py|/)|[\w/]+/\*\.toml)`", body):
            name = name.split("/*")[0]
            if not any((b / name).exists() for b in (base, ROOT / "parmpm", ROOT)):
                stale.append(f"{layer}: {name}")
    assert not stale, "\n".join(stale)


def test_the_docs_have_examples_to_check():
    assert len(RUNNABLE) >= 2 and len(SCENES) >= 3


@pytest.mark.parametrize("code, runnable", RUNNABLE)
def test_python_example_runs(code, runnable, tmp_path):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(ROOT),
                                                                      os.environ.get("PYTHONPATH")])))
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]


@pytest.mark.parametrize("text, runnable", SCENES)
def test_toml_scene_loads(text, runnable, tmp_path):
    path = tmp_path / "scene.toml"
    path.write_text(text, encoding="utf-8")
    parmpm.load_scene(path)  # raises SceneError with a one-line message on any bad key


# --- the site ------------------------------------------------------------------------------------
def _docs_tools() -> bool:
    return all(importlib.util.find_spec(m) for m in ("mkdocs", "material", "mkdocstrings",
                                                     "mkdocstrings_handlers.python",
                                                     "mkdocs_gen_files"))


needs_mkdocs = pytest.mark.skipif(not _docs_tools(), reason="the docs extra (mkdocs) is not installed")


def _site_copy(tmp_path: Path) -> Path:
    """mkdocs.yml and docs/ copied, the code linked in: a build there is the real one."""
    shutil.copy(ROOT / "mkdocs.yml", tmp_path / "mkdocs.yml")
    shutil.copytree(DOCS, tmp_path / "docs", ignore=shutil.ignore_patterns("__pycache__"))
    for package in ("parmpm", "decomposition"):
        (tmp_path / package).symlink_to(ROOT / package, target_is_directory=True)
    return tmp_path


def _build(folder: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir",
                           str(folder / "site")], cwd=folder, env=dict(os.environ, **MKDOCS_ENV),
                          capture_output=True, text=True, timeout=300)


@pytest.mark.docs
@needs_mkdocs
def test_site_builds_strict(tmp_path):
    proc = _build(_site_copy(tmp_path))
    assert proc.returncode == 0, proc.stderr[-3000:]
    for page in ("index.html", "reference/scene-keys/index.html", "reference/cli/index.html",
                 "api/parmpm.scene/index.html"):
        assert (tmp_path / "site" / page).is_file(), page


@pytest.mark.docs
@needs_mkdocs
def test_broken_cross_reference_fails_the_build(tmp_path):
    folder = _site_copy(tmp_path)
    with open(folder / "docs" / "concepts" / "methods.md", "a", encoding="utf-8") as f:
        f.write("\nSee [a page that is not there](no_such_page.md) and "
                "[an anchor that is not there](../getting-started.md#no-such-anchor).\n")
    proc = _build(folder)
    assert proc.returncode != 0
    assert "no_such_page.md" in proc.stderr and "no-such-anchor" in proc.stderr, proc.stderr[-3000:]
