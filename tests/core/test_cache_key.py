"""numba's on-disk cache keyed to the whole package source (:mod:`parmpm.core.cache_key`).

numba's own freshness test looks at the cached kernel's file alone; a kernel's machine code also
holds the helpers it calls from other modules. The end-to-end tests copy ``parmpm`` and
``decomposition`` into a temporary folder, add two probe modules there (callers in one, callees of
every kernel flavour and a constant in the other), and run them in fresh interpreters: after an
edit of the callee module alone, every caller must give the new result (numba's per-file key ran
the old machine code) and a second run must load, not compile. They do so in each place numba
keeps a cache: ``NUMBA_CACHE_DIR``, the ``__pycache__`` beside the sources, and the user-wide
folder numba falls back to when the install is read-only.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
TIMEOUT_S = 300

CALLEE = """\
from parmpm.core.jit import helper_kernel, kernel

SCALE = {factor}


@kernel
def plain(x):
    return x * {factor}


@helper_kernel
def forced(x):
    return x * {factor}
"""

CALLER = """\
from parmpm._probe_callee import SCALE, forced, plain
from parmpm.core.jit import kernel, loop_kernel


@kernel
def call_plain(x):
    return plain(x)


@loop_kernel
def call_forced(a, out):
    for i in range(a.shape[0]):
        out[i] = forced(a[i])


@kernel
def call_constant(x):
    return x * SCALE
"""

PROBE = """\
import json

import numpy as np

import parmpm
from parmpm import _probe_caller as c

out = np.zeros(1)
c.call_forced(np.ones(1), out)
kernels = (c.call_plain, c.call_forced, c.call_constant)
print(json.dumps({"file": parmpm.__file__,
                  "values": [c.call_plain(1.0), float(out[0]),
                             c.call_constant(1.0)],
                  "compiled": sum(sum(k.stats.cache_misses.values()) for k in kernels),
                  "loaded": sum(sum(k.stats.cache_hits.values()) for k in kernels)}))
"""


def _copy_packages(dest: Path) -> Path:
    for name in ("parmpm", "decomposition"):
        shutil.copytree(REPO / name, dest / name,
                        ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    return dest


def _write_callee(pkg: Path, factor: float) -> None:
    (pkg / "parmpm" / "_probe_callee.py").write_text(CALLEE.format(factor=factor))


def _probe(pkg: Path, env: dict) -> dict:
    proc = subprocess.run([sys.executable, "-c", PROBE], cwd=pkg.parent, env=env,
                          capture_output=True, text=True, timeout=TIMEOUT_S)
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout.strip().splitlines()[-1])
    assert Path(result["file"]).resolve() == (pkg / "parmpm" / "__init__.py").resolve()
    return result


def _cached_files(where: Path) -> list[str]:
    return sorted(p.name for p in where.rglob("_probe_*.nb[ic]"))


@pytest.mark.parametrize("location", ["NUMBA_CACHE_DIR", "in-tree", "user-wide"])
def test_an_edited_callee_in_another_module_is_never_run_stale(tmp_path, location):
    pkg = _copy_packages(tmp_path / "pkg")
    _write_callee(pkg, 1.0)
    (pkg / "parmpm" / "_probe_caller.py").write_text(CALLER)
    drop = ("NUMBA_CACHE_DIR", "NUMBA_CACHE_LOCATOR_CLASSES", "NUMBA_DISABLE_JIT")
    env = {k: v for k, v in os.environ.items() if k not in drop}
    env.update(PYTHONPATH=str(pkg), PYTHONDONTWRITEBYTECODE="1",
               XDG_CACHE_HOME=str(tmp_path / "user"))
    if location == "NUMBA_CACHE_DIR":
        env["NUMBA_CACHE_DIR"] = str(tmp_path / "cache")
        where = tmp_path / "cache"
    elif location == "in-tree":
        where = pkg / "parmpm" / "__pycache__"
    else:  # a read-only install: no __pycache__ can be made beside the sources (a file is
        # there), so numba caches in the user's folder (works for root too, unlike chmod)
        for name in ("parmpm", "decomposition"):
            (pkg / name / "__pycache__").write_text("not a folder")
        where = tmp_path / "user" / "numba"

    first = _probe(pkg, env)
    assert first["values"] == [1.0] * 3 and first["compiled"] == 3
    warm = _probe(pkg, env)
    assert warm["values"] == [1.0] * 3
    assert warm["compiled"] == 0 and warm["loaded"] == 3  # a warm run loads, never compiles
    files = _cached_files(where)
    assert any(f.startswith("_probe_caller.call_plain") for f in files), files

    for factor in (2.0, 3.0):  # only the callee module changes
        _write_callee(pkg, factor)
        edited = _probe(pkg, env)
        assert edited["values"] == [factor] * 3, \
            f"{location}: the callers ran the previous callee {edited['values']}"
        again = _probe(pkg, env)
        assert again["values"] == [factor] * 3 and again["compiled"] == 0
        # the stale entries are overwritten, not piled up
        assert _cached_files(where) == files


CHECKOUT_TEST = """\
import numba

from parmpm._probe_callee import plain
from parmpm.core.jit import kernel

OWN = {own}


@kernel
def call_from_a_test(x):
    return plain(x) + OWN


@numba.njit(cache=True)
def plain_numba_in_a_test(x):
    return plain(x) + OWN
"""

CHECKOUT_PROBE = """\
import json
import sys

sys.path.insert(0, "tests")
import _probe_test as t

kernels = (t.call_from_a_test, t.plain_numba_in_a_test)
print(json.dumps({"values": [k(1.0) for k in kernels],
                  "compiled": sum(sum(k.stats.cache_misses.values()) for k in kernels)}))
"""


def test_a_checkouts_test_kernels_are_never_run_stale(tmp_path):
    """A kernel defined in a source checkout's ``tests/`` (beside ``pyproject.toml``) that calls a
    package helper gives the new result after an edit of the helper, and after one of its own
    file; a warm run loads it."""
    top = _copy_packages(tmp_path / "checkout")
    (top / "pyproject.toml").write_text("[project]\nname = 'probe'\n")
    (top / "tests").mkdir()
    _write_callee(top, 1.0)
    env = {k: v for k, v in os.environ.items()
           if k not in ("NUMBA_CACHE_LOCATOR_CLASSES", "NUMBA_DISABLE_JIT")}
    env.update(PYTHONPATH=str(top), PYTHONDONTWRITEBYTECODE="1",
               NUMBA_CACHE_DIR=str(tmp_path / "cache"))

    def probe(own: float) -> dict:
        (top / "tests" / "_probe_test.py").write_text(CHECKOUT_TEST.format(own=own))
        proc = subprocess.run([sys.executable, "-c", CHECKOUT_PROBE], cwd=top, env=env,
                              capture_output=True, text=True, timeout=TIMEOUT_S)
        assert proc.returncode == 0, proc.stderr
        return json.loads(proc.stdout.strip().splitlines()[-1])

    assert probe(0.0) == {"values": [1.0, 1.0], "compiled": 2}
    assert probe(0.0)["compiled"] == 0  # warm: loaded
    _write_callee(top, 2.0)  # the package helper changes, the test file does not
    assert probe(0.0)["values"] == [2.0, 2.0]
    assert probe(5.0)["values"] == [7.0, 7.0]  # the test file changes


# --- the key, in this process -------------------------------------------------------------------
def test_the_digest_covers_every_module_and_only_the_sources(tmp_path):
    from parmpm.core.cache_key import digest_of

    root = tmp_path / "pkg"
    (root / "sub").mkdir(parents=True)
    (root / "a.py").write_text("A = 1\n")
    (root / "sub" / "b.py").write_text("B = 1\n")
    base = digest_of([str(root)])
    assert digest_of([str(root)]) == base
    (root / "__pycache__").mkdir()
    (root / "__pycache__" / "a.cpython-311.pyc").write_bytes(b"\0")
    (root / "sub" / "notes.txt").write_text("not source")
    assert digest_of([str(root)]) == base  # caches and other files do not count
    (root / "sub" / "b.py").write_text("B = 2\n")  # a module in a subpackage
    assert digest_of([str(root)]) != base
    (root / "sub" / "b.py").write_text("B = 1\n")
    assert digest_of([str(root)]) == base
    (root / "sub" / "b.py").rename(root / "sub" / "c.py")  # a module renamed
    assert digest_of([str(root)]) != base


def test_every_cached_kernel_of_both_packages_is_keyed_to_the_digest():
    """All of them: ``@kernel`` and friends, the overloads' wrappers and the ``@njit(cache=True)``
    of :mod:`decomposition.halo`, which does not import :mod:`parmpm.core.jit`."""
    import numba
    from numba.core.dispatcher import Dispatcher

    import parmpm.driver.simulation  # noqa: F401 (imports every kernel module of a run)
    from parmpm.core.cache_key import is_keyed, source_digest

    kernels = {f"{name}.{attr}": is_keyed(obj) for name, module in list(sys.modules.items())
               if module is not None and name.split(".")[0] in ("parmpm", "decomposition")
               for attr, obj in list(vars(module).items()) if isinstance(obj, Dispatcher)}
    assert len(kernels) > 50 and "decomposition.halo._owner_rows" in kernels
    assert [k for k, keyed in kernels.items() if keyed is False] == []

    @numba.njit(cache=True)
    def in_a_test(x):  # the checkout's tests: keyed, with this file's own stamp too
        return x

    assert is_keyed(in_a_test) is True
    stamp = in_a_test._cache._cache_file._source_stamp
    assert stamp[:2] == ("parmpm-sources", source_digest()) and len(stamp) == 3
    from decomposition.halo import _owner_rows
    assert _owner_rows._cache._cache_file._source_stamp == ("parmpm-sources", source_digest())


def test_kernels_outside_the_packages_and_their_checkout_keep_numbas_key(tmp_path, monkeypatch):
    (tmp_path / "elsewhere_probe.py").write_text(
        "import numba\n\n\n@numba.njit(cache=True)\ndef elsewhere(x):\n    return x\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    import elsewhere_probe
    from parmpm.core.cache_key import is_keyed

    assert is_keyed(elsewhere_probe.elsewhere) is False


def test_kernels_decorated_before_the_key_is_installed_are_re_keyed():
    """``decomposition`` imported first (it never imports parmpm): its kernels are re-keyed when
    :mod:`parmpm.core.jit` comes."""
    code = ("import decomposition.halo as h\n"
            "from parmpm.core.cache_key import is_keyed\n"
            "before = is_keyed(h._owner_rows)\n"
            "import parmpm.core.jit\n"
            "print(before, is_keyed(h._owner_rows), is_keyed(h._ghost_copy))\n")
    env = dict(os.environ, PYTHONPATH=str(REPO))
    proc = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                          timeout=TIMEOUT_S)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == ["False", "True", "True"]


def test_an_index_naming_a_module_that_no_longer_exists_is_stale(tmp_path, monkeypatch):
    """A cache index written before a module moved names the old module in its pickled types;
    numba unpickles it before the freshness test and raised ModuleNotFoundError at the kernel's
    first call. Keyed indexes now count as stale (compiled again); others fail as before."""
    import pickle

    from numba.core import caching

    from parmpm.core.cache_key import STAMP_TAG, install

    install()
    gone = tmp_path / "gone_module_for_the_index.py"
    gone.write_text("class Record:\n    pass\n", encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    import gone_module_for_the_index as mod

    def index(name, stamp):
        cache = caching.IndexDataCacheFile(str(tmp_path), name, stamp)
        with open(cache._index_path, "wb") as f:
            pickle.dump(cache._version, f, protocol=-1)
            f.write(pickle.dumps((stamp, {"sig": mod.Record()}), protocol=-1))
        return cache

    keyed, plain = index("keyed", (STAMP_TAG, "digest")), index("plain", (1.0, 2))
    assert isinstance(keyed._load_index()["sig"], mod.Record)  # while the module exists: read
    monkeypatch.delitem(sys.modules, "gone_module_for_the_index")
    gone.unlink()
    assert keyed._load_index() == {}
    with pytest.raises(ModuleNotFoundError):
        plain._load_index()
