"""Output folders: a run claims its folder before it writes, and never takes another run's.

A run writes ``parmpm-run.json`` (the *marker*: run id, the ids of the runs it continues, scene,
start time, the files it writes, the host and pid of its rank 0) into its output folder before
anything else, created with ``O_EXCL`` so two runs started at once cannot both claim one folder,
and holds the lock of ``parmpm-run.lock`` while it runs (:mod:`parmpm.io.run_lock`: released by
the OS when the process dies), so that whether the folder's run is still going can be told. A
folder *holds a run* when it has a marker, or (runs of older parmpm versions) a
``summary.json``, a checkpoint or an XDMF series. The rules:

* a folder is *free* when it is empty or missing (parmpm's lock and temporary files aside);
  one that holds no run but files parmpm did not write (a user's scene, mesh, particle file,
  folder: anything without a marker) is not;
* the default folder (``parmpm-out/<scene>``, or ``restart_<step>`` beside a checkpoint) is used
  when free, else the first free ``<folder>_2``, ``<folder>_3``, …: repeating a command never
  overwrites the last results;
* an explicit ``--out`` folder that holds another run, or files parmpm did not write, is refused
  with one line naming them, unless the user passes ``--overwrite``, which deletes that run's
  outputs (its marker's files, its checkpoints and snapshot series with their ``.parts``
  folders, ``summary.json``; files parmpm did not write are kept, except those the new run
  writes by name; the marker last) before the new run starts;
* a run that is still going is never overwritten: the refusal names its folder, host and pid; a
  run that crashed or was killed (its lock free) can be;
* no run deletes or replaces a file it reads (:class:`RunInput`: its scene file, its bodies'
  mesh, surface and particle files, a restart's checkpoint; through symbolic links, and inside
  the ``.parts`` folders ``--overwrite`` deletes): the folder is refused in one line naming the
  file, with or without ``--overwrite``. A restart into the folder of the checkpoint it
  continues is such a folder (keeping that checkpoint would also leave one of the old run's
  files, claimed by neither marker, in the new run's folder, for the next ``--overwrite`` to
  delete);
* a restart is a run of its own: it writes into a folder of its own (by default
  ``restart_<step>`` beside the checkpoint), never into the folder of the run it continues, so
  neither can overwrite or prune the other's checkpoints;
* an ``--out`` that is a file, or a symbolic link to nothing, is refused saying so.

Claiming is also the writability probe: a read-only or missing-permission folder fails here,
before the run, with one line.
"""
from __future__ import annotations

import json
import os
import shutil
import time
from pathlib import Path

from parmpm.core.errors import ParmpmError
from parmpm.io import run_lock
from parmpm.io.run_contents import (MARKER, RunInput, check_inputs, describe, doomed, foreign,
                                    holds_run, not_free, read_marker)

__all__ = ["MARKER", "MAX_SUFFIX", "Claim", "RunInput", "claim", "holds_run", "read_marker",
           "update_marker"]

#: folders tried after the default one is taken: <folder>_2 ... <folder>_MAX_SUFFIX
MAX_SUFFIX = 999


def _remove_run(folder: Path) -> None:
    """``--overwrite``: delete the run in ``folder`` (:func:`~parmpm.io.run_contents.doomed`; the files
    the new run reads are checked before); the marker goes last, so a failure half way leaves
    a folder that still holds a run (and ``--overwrite`` again finishes the job), never an
    unclaimed half."""
    files, dirs = doomed(folder)
    marker = files.pop() if files and files[-1].name == MARKER else None
    for path in files:
        path.unlink(missing_ok=True)
    for d in dirs:
        shutil.rmtree(d)
    if marker is not None:
        marker.unlink(missing_ok=True)


def _create_marker(folder: Path, marker: dict, replace: bool) -> None:
    path = folder / MARKER
    text = json.dumps(marker, indent=2) + "\n"
    if replace:
        tmp = folder / f".{MARKER}.{os.getpid()}.tmp"
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, path)
        return
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
    with os.fdopen(fd, "w", encoding="utf-8") as f:
        f.write(text)


def _live(folder: Path, record: dict) -> ParmpmError:
    return ParmpmError(f"output folder '{folder}' belongs to a run that is still going "
                       f"({run_lock.who(record)}); wait for it to end or stop it, or choose "
                       "another --out")


def _not_a_folder(candidate: Path) -> str | None:
    """Why ``candidate`` cannot be an output folder (a file, a link to nothing), or None."""
    if candidate.is_symlink() and not candidate.exists():
        return (f"output folder '{candidate}' is a symbolic link to '{os.readlink(candidate)}', "
                "which does not exist; create that folder, or choose another --out")
    if candidate.exists() and not candidate.is_dir():
        return f"output folder '{candidate}' is a file, not a folder"
    return None


class Claim:
    """A claimed output folder (``folder``) and the lock that says its run is alive (None where
    the filesystem has no locks), held by this process until :meth:`release` (or its exit)."""

    def __init__(self, folder: Path, lock: run_lock.RunLock | None):
        self.folder, self.lock, self.held = folder, lock, True

    def release(self) -> None:
        """The run is over: its marker says so (``ended``: what tells without locks), then the
        lock is dropped. Idempotent; never raises."""
        if not self.held:
            return
        self.held = False
        try:
            update_marker(self.folder, ended=time.strftime("%Y-%m-%dT%H:%M:%S%z"))
        except Exception:  # noqa: BLE001 - never hides the run's own end; the lock alone tells
            pass
        if self.lock is not None:
            self.lock.release()
            self.lock = None


def _take(candidate: Path, marker: dict, explicit: bool, overwrite: bool,
          inputs) -> tuple[str, object]:
    """Try to claim one folder: ("ok", the lock or None), or ("taken", why: the ParmpmError an
    explicit --out is refused with)."""
    held = candidate.exists() and holds_run(candidate)
    if held and not explicit:
        return "taken", None
    if held and not overwrite:  # refused either way: say whether that run is still going
        return "taken", _refusal(candidate)
    found = [] if held else foreign(candidate)
    if found and not explicit:
        return "taken", None
    # a file the run reads first (--overwrite would not help), before anything is written there
    why = check_inputs(candidate, inputs, marker, held) if held or found else None
    if why is not None or (found and not overwrite):
        return "taken", why or not_free(candidate, found, marker)
    _make_folder(candidate)
    lock = run_lock.take(candidate)
    if isinstance(lock, run_lock.Busy):
        return "taken", _live(candidate, lock.record or read_marker(candidate))
    if isinstance(lock, run_lock.NoLocks):
        lock = None
        why = _unlocked_run(candidate) if held else None
        if why is not None:
            return "taken", why
    return _mark(candidate, marker, held, lock, inputs)


def _holds_runs(candidate: Path) -> ParmpmError:
    return ParmpmError(
        f"output folder '{candidate}' holds {describe(candidate)}; choose another --out, "
        "or pass --overwrite to delete them and write there")


def _refusal(candidate: Path) -> ParmpmError:
    """Why a folder that holds a run is refused without --overwrite: its run is still going, or
    the folder holds runs."""
    probe = run_lock.take(candidate, create=False)
    if isinstance(probe, run_lock.RunLock):
        probe.release()
    elif isinstance(probe, run_lock.Busy):
        return _live(candidate, probe.record or read_marker(candidate))
    return _holds_runs(candidate)


def _make_folder(candidate: Path) -> None:
    try:
        candidate.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        for above in candidate.parents:  # "File exists": say what is in the way
            problem = _not_a_folder(above)
            if problem:
                raise ParmpmError(f"cannot create output folder '{candidate}': "
                                  + problem.replace("output folder ", "", 1)) from None
        raise ParmpmError(f"cannot create output folder '{candidate}': "
                          f"{exc.strerror or exc}") from None


def _unlocked_run(candidate: Path) -> ParmpmError | None:
    """On a filesystem without locks, whether the run that holds ``candidate`` may still be
    going, by its marker's record (None: it has ended)."""
    record = read_marker(candidate) or {}
    alive = run_lock.alive_by_record(record)
    if alive:
        return _live(candidate, record)
    if alive is None:
        return ParmpmError(
            f"cannot tell whether the run in output folder '{candidate}' "
            f"({run_lock.who(record)}) is still going: its filesystem offers no file "
            f"locks; if it has ended, delete '{candidate / MARKER}' and run again")
    return None


def _mark(candidate: Path, marker: dict, held: bool, lock, inputs) -> tuple[str, object]:
    """Clear the run ``candidate`` held (``held``: --overwrite) and write this run's marker;
    ("taken", why) when another run claimed the folder meanwhile. ``lock`` is released then."""
    try:
        if not held and holds_run(candidate):  # a run that came and went meanwhile
            if lock is not None:
                lock.release()
            return "taken", _holds_runs(candidate)
        why = check_inputs(candidate, inputs, marker, held)  # the folder changed meanwhile
        if why is not None:
            if lock is not None:
                lock.release()
            return "taken", why
        if held:
            _remove_run(candidate)
        _create_marker(candidate, marker, replace=False)
    except FileExistsError:  # another run (without locks) claimed it this instant
        if lock is not None:
            lock.release()
        return "taken", ParmpmError(f"output folder '{candidate}' was just claimed by another "
                                    "run; choose another --out")
    except BaseException:
        if lock is not None:
            lock.release()
        raise
    return "ok", lock


def claim(folder, marker: dict, *, explicit: bool, overwrite: bool = False,
          inputs=()) -> Claim:
    """Claim an output folder for the run described by ``marker`` (rank 0 only); the
    :class:`Claim` holds its lock until released.

    ``explicit``: the user named the folder (``--out``), so it is used or refused, never renamed.
    ``inputs``: the files the run reads (:class:`RunInput`, or paths), which no claim deletes or
    replaces. A folder whose run is still going is never taken, with or without
    ``--overwrite`` (:mod:`parmpm.io.run_lock`).
    """
    folder = Path(folder)
    marker = dict(marker, started=time.strftime("%Y-%m-%dT%H:%M:%S%z"), **run_lock.me())
    candidates = [folder] if explicit else \
        [folder] + [folder.with_name(f"{folder.name}_{k}") for k in range(2, MAX_SUFFIX + 1)]
    try:
        for candidate in candidates:
            problem = _not_a_folder(candidate)
            if problem:
                if explicit:
                    raise ParmpmError(problem)
                continue
            verdict, result = _take(candidate, marker, explicit, overwrite, inputs)
            if verdict == "ok":
                return Claim(candidate, result)
            if explicit:
                raise result
    except OSError as exc:
        where = exc.filename or folder
        raise ParmpmError(f"cannot write to output folder '{where}': "
                          f"{exc.strerror or exc}") from None
    raise ParmpmError(f"output folders '{folder}' to '{candidates[-1].name}' all hold other runs "
                      "or files parmpm did not write; choose another --out")


def update_marker(folder: Path, **fields) -> None:
    """Add ``fields`` to the marker of a folder this run has claimed (atomic replace)."""
    folder = Path(folder)
    marker = read_marker(folder) or {}
    marker.update(fields)
    _create_marker(folder, marker, replace=True)
