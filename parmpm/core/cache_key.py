"""numba's on-disk cache keyed to the whole source of parmpm and ``decomposition``.

numba checks a cached kernel against the source file of the kernel alone (its modification time
and size, or from numba 0.6x its content): a kernel's machine code also holds every helper it
calls, inlined or linked in, from any module, and the constants it read. After an edit of
``materials/neo_hookean.py`` alone, the kernels calling its stress law loaded the old machine code
from the cache and ran the old law without a word (a ``git pull`` into an editable install, an
upgrade into the same place, a developer's edit).

So every kernel of the two packages gets one source stamp: a digest of every ``.py`` file of both
(:func:`source_digest`, computed once per process: ~60 files, a few milliseconds). Any change to
any module makes every cached kernel stale; numba then compiles it again and overwrites its
index (entries numbered from 1, so old data files are reused, never piled up: the cache of a
kernel stays as large as the signatures it was compiled for).

How: numba picks, per kernel, the first of ``CacheImpl._locator_classes`` that takes its source
file: ``NUMBA_CACHE_DIR`` when set, else the ``__pycache__`` beside the source when writable, else
a user-wide folder (``~/.cache/numba``). :func:`install` puts in front of them one subclass of each
that takes only the files of these packages and returns the digest as the stamp: the same
folders as before, a different freshness test. The locators are derived from the classes numba has
(their names changed between 0.59 and 0.6x), so the same code serves every numba from 0.59 on.
Files elsewhere (other packages' kernels) keep numba's own locators; ``NUMBA_CACHE_LOCATOR_CLASSES``
(numba 0.6x) replaces numba's list, these locators with it: who sets it keys the cache numba's way.

A source checkout's tests and scripts (``tests/``, ``run_scripts/`` beside ``pyproject.toml``)
define kernels of their own that call the packages' helpers; numba's key would run them stale
after an edit of those helpers (a test passed on the old code of the helper it tested). Theirs
are keyed to the digest and to their own file's stamp (:func:`in_checkout`).

Kernels already decorated when :func:`install` runs (``decomposition.halo``'s, if
``decomposition`` was imported before :mod:`parmpm.core.jit`) are re-keyed. A process that uses
``decomposition`` without ever importing :mod:`parmpm.core.jit` keeps numba's per-file stamp for those
few kernels.
"""
from __future__ import annotations

import functools
import hashlib
import importlib.util
import os
import pickle
import sys

#: the packages whose kernels are keyed, and whose sources make the key
PACKAGES = ("parmpm", "decomposition")
#: the folders of a source checkout whose kernels are keyed too (with their own file's stamp)
CHECKOUT_FOLDERS = ("tests", "run_scripts")
#: a tag in the stamp: an index written by plain numba never matches it
STAMP_TAG = "parmpm-sources"


@functools.lru_cache(maxsize=1)
def package_roots() -> tuple[str, ...]:
    """The folders of :data:`PACKAGES` (real paths), found without importing them."""
    roots = []
    for name in PACKAGES:
        spec = importlib.util.find_spec(name)
        if spec is not None and spec.submodule_search_locations:
            roots.extend(os.path.realpath(p) for p in spec.submodule_search_locations)
    return tuple(roots)


def digest_of(roots) -> str:
    """SHA-256 of every ``.py`` file under ``roots``: its path (relative to its root, with the
    root's name) and its bytes, in sorted order. ``__pycache__`` and hidden folders are skipped."""
    h = hashlib.sha256()
    for root in roots:
        base = os.path.basename(root)
        for folder, subfolders, names in os.walk(root):
            subfolders[:] = sorted(d for d in subfolders
                                   if d != "__pycache__" and not d.startswith("."))
            for name in sorted(n for n in names if n.endswith(".py")):
                path = os.path.join(folder, name)
                with open(path, "rb") as f:
                    data = f.read()
                rel = os.path.relpath(path, root).replace(os.sep, "/")
                h.update(f"{base}/{rel}\0{len(data)}\0".encode())
                h.update(data)
    return h.hexdigest()


@functools.lru_cache(maxsize=1)
def source_digest() -> str:
    """:func:`digest_of` the installed packages, once per process (the sources it imported)."""
    return digest_of(package_roots())


@functools.lru_cache(maxsize=1)
def checkout_roots() -> tuple[str, ...]:
    """``tests/`` and ``run_scripts/`` of the source checkout the packages live in (the folder
    above them holds ``pyproject.toml``); none for an installed copy."""
    roots = set()
    for root in package_roots():
        top = os.path.dirname(root)
        if os.path.isfile(os.path.join(top, "pyproject.toml")):
            roots.update(os.path.join(top, name) for name in CHECKOUT_FOLDERS
                         if os.path.isdir(os.path.join(top, name)))
    return tuple(sorted(roots))


def _under(py_file: str, roots) -> bool:
    try:
        path = os.path.realpath(py_file)
    except (OSError, ValueError):
        return False
    return any(path.startswith(root + os.sep) for root in roots)


def in_packages(py_file: str) -> bool:
    """Whether ``py_file`` is a source file of :data:`PACKAGES`."""
    return _under(py_file, package_roots())


def in_checkout(py_file: str) -> bool:
    """Whether ``py_file`` is a test or script of the packages' source checkout."""
    return _under(py_file, checkout_roots())


class _SourceKeyed:
    """Mixin over one of numba's file-backed locators: same folder, the packages' digest as the
    source stamp, for the packages' own files and (with numba's stamp of the file beside it)
    their checkout's tests and scripts."""

    parmpm_keyed = True

    def get_source_stamp(self):
        if in_packages(self._py_file):
            return STAMP_TAG, source_digest()
        return STAMP_TAG, source_digest(), super().get_source_stamp()

    @classmethod
    def from_function(cls, py_func, py_file):
        if not (in_packages(py_file) or in_checkout(py_file)):
            return None
        return super().from_function(py_func, py_file)


def _keyed_locators(caching) -> list[type]:
    """One :class:`_SourceKeyed` subclass per file-backed locator numba has, in numba's order
    (``NUMBA_CACHE_DIR``, in-tree ``__pycache__``, user-wide); zip archives are left to numba."""
    mixin = caching._SourceFileBackedLocatorMixin
    return [type(f"SourceKeyed{cls.__name__.lstrip('_')}", (_SourceKeyed, cls), {})
            for cls in caching.CacheImpl._locator_classes
            if issubclass(cls, mixin) and "Zip" not in cls.__name__]


def installed() -> bool:
    from numba.core import caching

    return any(getattr(c, "parmpm_keyed", False) for c in caching.CacheImpl._locator_classes)


def install() -> None:
    """Key every kernel of :data:`PACKAGES` decorated from now on to :func:`source_digest`, and
    re-key those decorated already. Idempotent; called by :mod:`parmpm.core.jit` on import, before any
    kernel is decorated."""
    from numba.core import caching

    if installed():
        return
    if not all(os.path.isdir(root) for root in package_roots()):
        return  # an import from an archive: no folder to digest, numba's own stamps stay
    caching.CacheImpl._locator_classes = [*_keyed_locators(caching),
                                          *caching.CacheImpl._locator_classes]
    index_file = caching.IndexDataCacheFile
    if not getattr(index_file._load_index, "parmpm_tolerant", False):
        index_file._load_index = tolerant_index_loader(index_file._load_index)
    _rekey_loaded()


def tolerant_index_loader(load):
    """numba unpickles a cache index before it compares its source stamp: an index written by
    sources whose modules have since moved or been renamed (the types of its signatures name
    them) raised ``ModuleNotFoundError`` at the first call of the kernel instead of counting as
    stale. For an index keyed here the failure means stale: the kernel compiles and overwrites
    it. Other indexes keep numba's behaviour."""
    @functools.wraps(load)
    def _load_index(self):
        try:
            return load(self)
        except (ImportError, AttributeError, EOFError, ValueError, pickle.UnpicklingError):
            stamp = getattr(self, "_source_stamp", None)
            if isinstance(stamp, tuple) and stamp[:1] == (STAMP_TAG,):
                return {}
            raise
    _load_index.parmpm_tolerant = True
    return _load_index


def _rekey_loaded() -> None:
    """Give the cached dispatchers of modules imported before :func:`install` a keyed cache."""
    from numba.core.dispatcher import Dispatcher

    for name, module in list(sys.modules.items()):
        if module is None or name.split(".")[0] not in PACKAGES:
            continue
        for obj in list(vars(module).values()):
            if isinstance(obj, Dispatcher) and is_keyed(obj) is False:
                obj.enable_caching()


def is_keyed(dispatcher) -> bool | None:
    """True when ``dispatcher``'s cache is keyed to the packages' digest, False when it is cached
    the plain numba way, None when it is not cached on disk."""
    impl = getattr(getattr(dispatcher, "_cache", None), "_impl", None)
    if impl is None:
        return None
    return bool(getattr(impl.locator, "parmpm_keyed", False))
