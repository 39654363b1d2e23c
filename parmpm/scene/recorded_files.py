"""What a run records of the files its bodies are read from, so that a restart never needs them.

A run's resolved scene gives every body file's size and SHA-256 (``file_size``,
``file_sha256``), and each of its checkpoints every body's global-id range and a file body's
bounds (:func:`body_records`). A restart registers those records (:func:`remember`) before it
loads the scene it stores. From then on a file body whose file is gone, or no longer has the
recorded digest, is *detached* (:func:`detached`): what the scene's checks and the set-up ask
of it — its bounds (the grid check, the exterior layer, the patch size, the memory estimate) and
its particle count — comes from the record, and its particles come from the checkpoint, never
from the file a user has since re-meshed, moved or deleted. Only what would need the file's
contents again refuses, in one line (:mod:`parmpm.scene.body_files`).

Without records (a new run, a checkpoint written before they existed) nothing is detached: a
file whose digest differs from the scene's ``file_sha256`` is read as it is now, with one
warning saying that it changed since the scene was recorded.

The same record serves a parallel run's other ranks (:func:`file_records`, :func:`adopt`): rank
0 reads a mesh or particle file once, checking the scene, and hands every other rank the bounds
and count it found (:func:`parmpm.scene.agreement.load_shared_scene`), which those ranks answer
from (:func:`shared`) instead of reading the file; the particles themselves come from rank 0 at
set-up (:mod:`parmpm.driver.listed_share`).
"""
from __future__ import annotations

import functools
import hashlib
import os
import stat
from typing import NamedTuple

#: the bytes read at a time while hashing a body file
CHUNK = 1 << 22


class Recorded(NamedTuple):
    """A file body as a run saw it: its bounds and how many particles it made."""
    lo: tuple[float, ...]
    hi: tuple[float, ...]
    count: int


#: (file, sha256, shape, groups, split, step) -> Recorded, from the checkpoint a restart reads
_RECORDS: dict[tuple, Recorded] = {}
#: the same key -> Recorded, as rank 0 read the file (a parallel run's other ranks)
_SHARED: dict[tuple, Recorded] = {}
#: bodies whose particles are listed (one per quadrature point or file row), not a lattice; their
#: file records are shared (a surface's inside needs the whole file)
LISTED_SHAPES = ("mesh", "particles")


def stamp(path: str) -> tuple:
    """``(path, size, mtime_ns)`` of a regular file, ``(path, None, None)`` for anything else
    (gone, a folder, a FIFO: never opened here)."""
    try:
        st = os.stat(path)
    except (OSError, ValueError):
        return (path, None, None)
    if not stat.S_ISREG(st.st_mode):
        return (path, None, None)
    return (path, st.st_size, st.st_mtime_ns)


@functools.lru_cache(maxsize=32)
def _digest(stamp_: tuple) -> tuple[int, str] | None:
    path, size, _ = stamp_
    if size is None:
        return None
    h = hashlib.sha256()
    try:
        with open(path, "rb") as f:
            while block := f.read(CHUNK):
                h.update(block)
    except OSError:
        return None
    return size, h.hexdigest()


def digest(path: str) -> tuple[int, str] | None:
    """``(size, SHA-256 hex)`` of the regular file ``path`` (read once per content stamp), None
    when it is not one or cannot be read."""
    return _digest(stamp(path))


def key_of(body) -> tuple:
    """The record's key: the file as the scene recorded it and what the body takes of it (a
    mesh's groups and split, a particle file's step)."""
    return _key(body.file, getattr(body, "file_sha256", None), body.shape,
                getattr(body, "groups", None), getattr(body, "split", None),
                getattr(body, "step", None))


def _key(file, sha, shape, groups, split, step) -> tuple:
    mesh = shape == "mesh"
    return (file, sha, shape, tuple(groups) if mesh and groups is not None else None,
            int(split) if mesh else None, step if shape == "particles" else None)


def changed(body) -> bool:
    """Whether a file body recorded with a digest no longer finds that file (gone or changed)."""
    sha = getattr(body, "file_sha256", None)
    if sha is None:
        return False
    now = digest(body.file)
    return now is None or now[1] != sha


def recorded(body) -> Recorded | None:
    """The restart's record of a file body, if one was registered."""
    return _RECORDS.get(key_of(body))


def detached(body) -> bool:
    """Whether a file body is answered from the restart's record instead of its file: it has a
    record and its file is gone or changed."""
    return recorded(body) is not None and changed(body)


def body_records(bodies, ranges) -> list[dict]:
    """Every body's record for a checkpoint: its global-id range ``ids`` and, for a file body, the
    key the restart finds it by (:func:`key_of`) and its bounds (``bodies``: the scene's records;
    ``ranges``: ``[first, last)`` per body)."""
    out = []
    for body, (first, last) in zip(bodies, ranges):
        rec = {"ids": [int(first), int(last)]}
        if body.file is not None and getattr(body, "file_sha256", None) is not None:
            lo, hi = body.bounds()
            rec.update(file=body.file, file_sha256=body.file_sha256, shape=body.shape,
                       groups=None if body.groups is None else list(body.groups),
                       split=body.split, step=body.step,
                       lo=[float(v) for v in lo], hi=[float(v) for v in hi])
        out.append(rec)
    return out


def remember(records) -> list[tuple[int, int]] | None:
    """Register a checkpoint's body records (``None``: a checkpoint without them) and return the
    bodies' global-id ranges (None without records)."""
    if not records:
        return None
    for rec in records:
        if "file" in rec:
            key = _key(rec["file"], rec["file_sha256"], rec["shape"], rec.get("groups"),
                       rec.get("split"), rec.get("step"))
            first, last = rec["ids"]
            _RECORDS[key] = Recorded(tuple(rec["lo"]), tuple(rec["hi"]), int(last - first))
    return [(int(r["ids"][0]), int(r["ids"][1])) for r in records]


def file_records(bodies, count) -> list[dict]:
    """What rank 0 read of every mesh or particle file that has a digest: the key
    (:func:`key_of`) with the bounds and ``count(body)`` (``bodies``: the scene's records)."""
    out = []
    for body in bodies:
        if body.shape in LISTED_SHAPES and getattr(body, "file_sha256", None) is not None:
            lo, hi = body.bounds()
            out.append({"key": key_of(body), "lo": [float(v) for v in lo],
                        "hi": [float(v) for v in hi], "count": int(count(body))})
    return out


def adopt(records) -> None:
    """Register rank 0's :func:`file_records` on another rank (:func:`shared` answers from them)."""
    for rec in records:
        _SHARED[tuple(rec["key"])] = Recorded(tuple(rec["lo"]), tuple(rec["hi"]), rec["count"])


def shared(body) -> Recorded | None:
    """Rank 0's record of a mesh or particle body's file, if this rank adopted one."""
    if body.shape not in LISTED_SHAPES:
        return None
    return _SHARED.get(key_of(body))
