"""Every rank runs one scene: read once, shared, and compared (collective).

Each rank of an MPI job parses its own command line, and each used to read the scene file
itself, with nothing to check that they read the same: a file replaced while ``mpirun`` started
the ranks (an editor's atomic save, a script writing scenes) gave a run that exited 0 with a
mass belonging to neither version, and an MPMD launch (``mpirun -n 1 parmpm run a.toml : -n 1
parmpm run b.toml``) ran two densities in one job. ``scene.toml`` recorded rank 0's only.

Now (:func:`load_shared_scene`) rank 0 reads the file once and broadcasts its text to every rank
that names the same file (so a file replaced meanwhile is read once, as one version), each rank
resolves the text with its own ``--set``, and :func:`check_same_scene` compares a SHA-256 of
every rank's resolved scene (and, for a restart, of the checkpoint it continues): ranks that
would run different scenes all fail with one line naming a rank, the first key that differs and
both values. The cost is one broadcast of a page of TOML and one allgather of 64 characters.

Rank 0 resolves first; a rank whose input is rank 0's (the usual case) takes rank 0's resolved
scene, and with it what rank 0 read of the bodies' mesh and particle files (bounds, counts), so
that only rank 0 reads them (issue 43: set-up O(N/P)); the files' own checks and warnings are
rank 0's, as every rank's were the same. A mesh's element checks (degenerate, inverted, tangled)
are left to the set-up, which makes each rank's share of its particles on that rank and checks
their elements there (:func:`parmpm.scene.body_files.deferred_element_checks`).
"""
from __future__ import annotations

import hashlib
import json
import os
import tomllib
from collections.abc import Iterable
from pathlib import Path

from parmpm.core.collective import agree
from parmpm.core.errors import ParmpmError, SceneError
from parmpm.scene import load as scenes  # scenes.load_scene looked up at call time (tests replace it)
from parmpm.scene.body_files import count, deferred_element_checks
from parmpm.scene.load import (BOM, Scene, apply_overrides, read_scene_text, scene_from_toml,
                               scene_identity)
from parmpm.scene.recorded_files import adopt, file_records
from parmpm.scene.check import show

HOW = ("give every rank the same scene and --set (an MPMD launch, or a scene file changed while "
       "the ranks started)")


def scene_digest(data: dict, extra: str = "") -> str:
    """SHA-256 of a resolved scene (``Scene.data``: plain values, so JSON is exact: floats by
    their shortest repr) and ``extra`` (a restart's checkpoint)."""
    text = json.dumps(data, sort_keys=True, allow_nan=True, default=repr) + "\0" + extra
    return hashlib.sha256(text.encode()).hexdigest()


def first_difference(a, b, key: str = "") -> tuple[str, object, object] | None:
    """The first dotted key where ``a`` and ``b`` differ, with both values (None: equal)."""
    if isinstance(a, dict) and isinstance(b, dict):
        for k in list(a) + [k for k in b if k not in a]:
            found = first_difference(a.get(k), b.get(k), f"{key}.{k}" if key else str(k))
            if found:
                return found
        return None
    if isinstance(a, list) and isinstance(b, list) and len(a) == len(b):
        for i, (x, y) in enumerate(zip(a, b)):
            found = first_difference(x, y, f"{key}.{i}" if key else str(i))
            if found:
                return found
        return None
    return None if a == b and type(a) is type(b) else (key or "the scene", a, b)


def check_same_scene(comm, scene: Scene, extra: str = "", what: str | None = None) -> None:
    """Raise one ``SceneError`` on every rank when the ranks' resolved scenes (or ``extra``)
    differ (collective). ``what``: how a rank names its input in the message (default: the
    scene's source)."""
    if comm is None or comm.Get_size() == 1:
        return
    digests = comm.allgather(scene_digest(scene.data, extra))
    other = next((r for r, d in enumerate(digests) if d != digests[0]), None)
    if other is None:
        return
    mine = (what or scene.source, scene.data, extra)
    name0, data0, extra0 = comm.bcast(mine if comm.Get_rank() == 0 else None, root=0)
    name1, data1, extra1 = comm.bcast(mine if comm.Get_rank() == other else None, root=other)
    diff = first_difference(data0, data1)
    if diff is None:  # the same scene, another checkpoint
        raise SceneError(f"ranks were given different checkpoints: rank {other} restarts "
                         f"{name1} ({extra1}), rank 0 {name0} ({extra0}); give every rank the "
                         "same checkpoint and --set")
    key, v0, v1 = diff
    raise SceneError(f"ranks would run different scenes: rank {other} has {key} = {show(v1)} "
                     f"(from {name1}), rank 0 {show(v0)} (from {name0}); {HOW}")


def load_shared_scene(comm, source: str | Path, overrides: Iterable[str] = ()) -> Scene:
    """:func:`parmpm.scene.load.load_scene` for every rank of ``comm`` (collective; None or one
    rank: the plain load): the file is read by rank 0 only and shared with the ranks that name
    the same file; rank 0 resolves it first, reading its bodies' files, and a rank whose input
    (text, ``overrides``, working folder: :func:`input_digest`) is rank 0's takes rank 0's
    resolved scene and its mesh and particle files' bounds and counts
    (:func:`parmpm.scene.recorded_files.adopt`) without reading those files; a rank with
    another input resolves its own; then :func:`check_same_scene`. Any rank's problem is
    raised on every rank (the lowest rank's message)."""
    if comm is None or comm.Get_size() == 1:
        return scenes.load_scene(source, overrides)
    rank = comm.Get_rank()
    ident = scene_identity(source)
    read, problem = None, None
    if rank == 0:
        try:
            read = read_scene_text(source)
        except ParmpmError as exc:
            problem = str(exc)
    ident0, read0, problem0 = comm.bcast((ident, read, problem) if rank == 0 else None, root=0)
    scene, mine = None, None
    try:
        if ident == ident0:
            if problem0:
                raise SceneError(problem0)
            read = read0
        elif read is None:
            read = read_scene_text(source)
        mine = input_digest(read, overrides)
        if rank == 0:  # a mesh's element checks are the set-up's, on every rank's share
            with deferred_element_checks():
                scene = scene_from_toml(read[0], read[1], overrides, default_name=read[2])
        problem = None
    except ParmpmError as exc:
        problem = str(exc)
    scene = _from_rank_0(comm, scene, mine, read, overrides, problem)
    check_same_scene(comm, scene, what=f"'{scene.source}'")
    return scene


def _from_rank_0(comm, scene, mine, read, overrides, problem) -> Scene:
    """Rank 0's resolved scene, its files' records and its digest, broadcast; another rank with
    the same input digest takes them, one with another input resolves its own (collective)."""
    rank = comm.Get_rank()
    shared = None
    if rank == 0 and scene is not None:
        shared = (mine, scene.data, scene.source,
                  file_records(scene.spec.bodies, lambda b: count(b, scene.spec.dim)))
    shared = comm.bcast(shared, root=0)
    if rank != 0 and problem is None:
        try:
            if shared is not None and mine is not None and mine == shared[0]:
                adopt(shared[3])
                scene = Scene(shared[1], shared[2])
            elif shared is not None:  # rank 0's problem, if any, is raised below
                with deferred_element_checks():
                    scene = scene_from_toml(read[0], read[1], overrides, default_name=read[2])
        except ParmpmError as exc:
            problem = str(exc)
    agree(comm, problem, root=None, error=SceneError)
    return scene


def input_digest(read: tuple[str, str, str], overrides: Iterable[str]) -> str | None:
    """SHA-256 of what a rank resolves: the scene's text, label and default name, its
    ``overrides`` applied (None when they do not apply: the rank resolves its own, to say why),
    the working folder and home (relative and ``~`` paths of body files)."""
    text, label, default_name = read
    try:
        raw = tomllib.loads(text.removeprefix(BOM))
        origins = apply_overrides(raw, overrides, f"scene '{label}'")
    except (ParmpmError, ValueError, RecursionError):
        return None
    extra = "\0".join([label, default_name, os.getcwd(), os.path.expanduser("~"),
                       json.dumps(origins, sort_keys=True)])
    return scene_digest(raw, extra)
