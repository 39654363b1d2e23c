"""A file body's scene keys (``file``, a mesh's ``groups`` and ``split``, a particle file's
``step``, the recorded ``file_size`` and ``file_sha256``), checked so that every problem with
the file is one line naming ``bodies.N.file`` — before anything opens it (a FIFO, a directory,
a name no file system holds), then by reading it (:mod:`parmpm.scene.body_files.contents`).
"""
from __future__ import annotations

import math
import os
import re
import stat
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np

from parmpm.core.errors import SceneError
from parmpm.core.extremes import column_min_max
from parmpm.scene import recorded_files
from parmpm.scene.body_files.contents import (_groups_of, _mesh, _mesh_file, _particles, _stamp,
                                              _warn_once, bounds, count, element_checks_deferred,
                                              listed, surface)
from parmpm.scene.check import Checker, show

#: each file shape's own keys, and the dimensions it exists in
#: (``file_size``, ``file_sha256``: what the resolved scene records of the file,
#: :mod:`parmpm.scene.recorded_files`)
FILE_KEYS = {"mesh": ("file", "groups", "split", "file_size", "file_sha256"),
             "surface": ("file", "file_size", "file_sha256"),
             "particles": ("file", "step", "file_size", "file_sha256")}
FILE_DIMS = {"mesh": (2, 3), "surface": (3,), "particles": (1, 2, 3)}
#: the most sub-divisions per element edge (split^d times the particles of each element)
MAX_SPLIT = 16
#: the most particles a meshed body may make (as a particle file may hold)
MAX_MESH_PARTICLES = 2**31
#: the longest name in a path and the longest path, in bytes (Linux's NAME_MAX and PATH_MAX)
NAME_MAX, PATH_MAX = 255, 4096
#: how each file shape's errors name its file
LABELS = {"mesh": "mesh", "surface": "surface file", "particles": "particle file"}
#: what a path that is not a regular file is
KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
         (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
         (stat.S_ISSOCK, "a socket"))


def scene_folder(where: str) -> Path:
    """The folder a body's relative ``file`` is read from: the scene file's (``where`` is the
    checker's ``scene '<source>'``), else the working directory."""
    m = re.fullmatch(r"scene '(.*)'", where, re.DOTALL)
    source = m.group(1) if m else ""
    if source and not source.startswith("builtin:") and Path(source).is_file():
        return Path(source).resolve().parent
    return Path.cwd()


def files_read(scene) -> list[tuple[str, str]]:
    """The files a run of ``scene`` reads, each with how a refusal names it: its scene file (not
    a built-in) and its bodies' mesh, surface and particle files; a run's output folder must
    never delete or replace one (:mod:`parmpm.io.run_folder`)."""
    found = []
    source = str(scene.source)
    if not source.startswith("builtin:") and Path(source).is_file():
        found.append((source, "the scene file this run reads"))
    for i, body in enumerate(scene.data.get("bodies", [])):
        if body.get("shape") in FILE_KEYS and body.get("file"):
            found.append((body["file"], f"the {body['shape']} file of bodies.{i}"))
    return found


def check_file_body(c: Checker, key: str, t: dict, dim: int, shape: str,
                    materials: dict) -> tuple[dict, list, list]:
    """A file body's resolved keys (``file`` absolute, ``groups``, ``split``, ``step``) and its
    bounds; reads the file, so that every problem with it is one line naming ``key.file``."""
    fkey = f"{key}.file"
    name = c.string(fkey, c.required(key, t, "file", "a path to a file (relative: to the scene's "
                                                     "folder)"))
    if not name.strip():
        c.expected(fkey, "a path to a file", name)
    if "\0" in name:
        c.fail(fkey, f"{show(name)} holds a NUL byte; expected a path to a file")
    path = Path(os.path.expanduser(name))
    if not path.is_absolute():
        path = scene_folder(c.where) / path
    out: dict[str, Any] = {"file": os.path.abspath(path)}
    _regular(c, fkey, shape, out["file"])
    if shape == "mesh":
        out["groups"] = _groups(c, f"{key}.groups", t.get("groups"))
        out["split"] = c.integer(f"{key}.split", t.get("split", 1),
                                 f"an integer from 1 to {MAX_SPLIT}", lambda s: 1 <= s <= MAX_SPLIT)
    if shape == "particles":
        step = t.get("step")
        out["step"] = None if step is None else c.integer(f"{key}.step", step,
                                                          "an integer >= 0 (a run's step)",
                                                          lambda s: s >= 0)
    now = recorded_files.digest(out["file"])
    sha = _claimed(c, key, t)
    if sha is not None and (now is None or now[1] != sha):
        rec = recorded_files.recorded(_view(shape, {**out, "file_sha256": sha}))
        if rec is not None:  # a restart: the checkpoint holds what the file gave
            _warn_once(f"{key}.file: '{out['file']}' is {'gone' if now is None else 'changed'} "
                       "since the checkpoint this run continues: its particles, bounds and "
                       "count are the checkpoint's")
            if "file_size" in t:
                out["file_size"] = t["file_size"]
            out["file_sha256"] = sha
            return out, list(rec.lo), list(rec.hi)
        if now is not None:
            _warn_once(f"{key}.file: '{out['file']}' changed since this scene was recorded "
                       f"(sha256 {sha[:16]}…, {t.get('file_size', '?')} bytes; now "
                       f"{now[1][:16]}…, {now[0]} bytes): the run reads it as it is now")
    view = _view(shape, out)
    try:
        lo, hi = _check_surface(key, view) if shape == "surface" else bounds(view, dim)
        n = count(view, dim) if shape == "mesh" else 0
        if shape == "mesh" and n <= MAX_MESH_PARTICLES:  # its elements' checks (split 1: the same)
            if not element_checks_deferred():
                _mesh(_stamp(view.file), dim, _groups_of(view), 1)
            _warn_repeats(fkey, view, dim)
        data = listed(view, dim) if shape == "particles" else None
    except SceneError as exc:
        c.fail(fkey, str(exc))
    note = _particles(_stamp(view.file), dim, view.step)[2] if data is not None else ""
    if note:  # rows at one position: the body's mass counted again there
        _warn_once(f"{fkey}: {note}")
    names = None if data is None else data.material
    if data is not None:
        _check_volumes(fkey, out["file"], data, dim)
    moving = [k for k in ("velocity", "angular_velocity", "velocity_gradient") if k in t]
    if data is not None and data.velocity is not None and moving:
        c.fail(f"{key}.{moving[0]}", f"the particle file '{out['file']}' gives every particle's "
                                     "velocity; expected no initial velocity keys (or a file "
                                     "without velocities)")
    if n > MAX_MESH_PARTICLES:
        c.fail(f"{key}.split", f"{out['split']} makes {n} particles, more than "
                               f"{MAX_MESH_PARTICLES}; expected a smaller split")
    if names is not None:
        for name in np.unique(names):
            if str(name) not in materials:
                c.fail(fkey, f"particle file '{out['file']}' names material {show(str(name))}, "
                             "which the scene does not define (defined: "
                             + ", ".join(show(m) for m in materials) + ")")
    if now is not None:  # what the run read, recorded (recorded_files)
        out.update(file_size=now[0], file_sha256=now[1])
    return out, lo, hi


def _claimed(c: Checker, key: str, t: dict) -> str | None:
    """A recorded scene's ``file_sha256`` (and its ``file_size``, checked for form only)."""
    if "file_size" in t:
        c.integer(f"{key}.file_size", t["file_size"], "an integer >= 0 (the file's bytes)",
                  lambda n: n >= 0)
    if "file_sha256" not in t:
        return None
    sha = c.string(f"{key}.file_sha256", t["file_sha256"])
    if not re.fullmatch(r"[0-9a-f]{64}", sha):
        c.expected(f"{key}.file_sha256", "64 lower-case hex digits (the file's SHA-256)", sha)
    return sha


def _regular(c: Checker, fkey: str, shape: str, path: str) -> None:
    """Refuse, before anything opens it, a path no file can have (a name over NAME_MAX bytes, the
    whole over PATH_MAX) and one that is there but is no regular file: a FIFO blocks ``open()``
    until something writes to it; a directory, device or socket holds no body. A missing file is
    the reader's to report (it names the formats it expects). A particle ``.xdmf`` is read through
    its ``.h5``, which is checked too."""
    raw = os.fsencode(path)
    longest = max(raw.split(b"/"), key=len)
    if len(longest) > NAME_MAX:
        c.fail(fkey, f"{LABELS[shape]} {show(path)}: a name in the path is {len(longest)} bytes "
                     f"long; expected at most {NAME_MAX} bytes per name")
    if len(raw) >= PATH_MAX:
        c.fail(fkey, f"{LABELS[shape]} {show(path)}: the path is {len(raw)} bytes long; "
                     f"expected under {PATH_MAX}")
    paths = [path] + ([str(Path(path).with_suffix(".h5"))]
                      if shape == "particles" and path.lower().endswith(".xdmf") else [])
    for each in paths:
        try:
            mode = os.stat(each).st_mode
        except FileNotFoundError:
            continue
        except OSError as exc:
            c.fail(fkey, f"{LABELS[shape]} '{each}': cannot be read ({exc.strerror or exc})")
        if not stat.S_ISREG(mode):
            kind = next((k for test, k in KINDS if test(mode)), "not a file")
            c.fail(fkey, f"{LABELS[shape]} '{each}': is {kind}, not a regular file; expected "
                         f"a {LABELS[shape]}")


def _warn_repeats(fkey: str, body, dim: int) -> None:
    """One warning for the cells a mesh lists more than once (seeded once each): how many
    listings were dropped and the volume they would have added."""
    from parmpm.geometry.mesh import particles_per_element

    mesh = _mesh_file(_stamp(body.file), dim, _groups_of(body))[0]
    if mesh.repeats is None:
        return
    vol = _mesh(_stamp(body.file), dim, _groups_of(body), 1).vol
    per = np.concatenate([np.full(len(b.cells), particles_per_element(b.cell_type, 1))
                          for b in mesh.blocks])
    cell_vol = np.add.reduceat(vol, np.concatenate([[0], np.cumsum(per)[:-1]]))
    dropped = math.fsum(cell_vol * mesh.repeats)
    n, cells = int(mesh.repeats.sum()), int(np.count_nonzero(mesh.repeats))
    noun = "area" if dim == 2 else "volume"
    why = ("; Gmsh 2.2 writes a cell once per physical group"
           if body.file.lower().endswith(".msh") else "")
    _warn_once(f"{fkey}: mesh '{body.file}' lists {cells} cells more than once (the same nodes in "
               f"any order{why}): each is seeded once, dropping {n} repeated listings of {noun} "
               f"{dropped:.6g} m^{dim}")


def _view(shape: str, keys: dict) -> SimpleNamespace:
    """The few fields of a body the loaders read, before its record exists."""
    return SimpleNamespace(shape=shape, file=keys["file"], groups=keys.get("groups"),
                           split=keys.get("split", 1), step=keys.get("step"),
                           file_sha256=keys.get("file_sha256"))


def _groups(c: Checker, key: str, raw: Any) -> list | None:
    if raw is None:
        return None
    what = "a non-empty list of group names or ids (Gmsh physical groups, cell sets)"
    if not isinstance(raw, list) or not raw:
        c.expected(key, what, raw)
    for g in raw:
        if isinstance(g, bool) or not isinstance(g, (str, int)):
            c.expected(key, what, raw)
    return list(raw)


def _check_surface(key: str, body) -> tuple[list, list]:
    """The surface's bounds; a warning when it is not closed and consistently oriented."""
    _, _, s = surface(body)
    problems = [f"{n} {what} edges" for n, what in ((s.open_edges, "open"),
                                                  (s.nonmanifold_edges, "non-manifold"),
                                                  (s.misoriented_edges, "misoriented")) if n]
    if problems:
        _warn_once(f"{key}.file: surface '{body.file}' is not a closed, consistently oriented "
                   f"surface ({', '.join(problems)}); its inside is the generalised winding "
                   "number's guess near those edges")
    return list(s.lo), list(s.hi)


#: how many times its bounding box a particle file's volumes may sum to (a file written at a
#: compressed step holds reference volumes at current positions)
VOLUME_SLACK = 2.0


def _check_volumes(key: str, path: str, data, dim: int) -> None:
    """One warning when a particle file's volumes sum to more than :data:`VOLUME_SLACK` times
    the box of its points grown by a median particle's width (the box a lattice of them fills):
    a volume in the wrong unit, or 1e300, which a run would take as it is (issue 41)."""
    vol = np.asarray(data.vol, float)
    width = float(np.median(vol)) ** (1.0 / dim) if vol.size else 0.0
    lo, hi = column_min_max(np.asarray(data.x, float).reshape(-1, dim))
    box = float(np.prod(hi - lo + width))
    total = float(math.fsum(vol))
    if total > VOLUME_SLACK * box:
        unit = {1: "m", 2: "m²", 3: "m³"}[dim]
        _warn_once(f"{key}: the particles of '{path}' have volumes summing to {total:.4g} {unit}, "
                   f"{total / box:.3g} times the {box:.4g} {unit} their points span (grown by a "
                   "median particle's width): check the file's volumes and their unit")
