"""Output folders: a run claims its folder before it writes, and never takes another run's.

A run writes ``parmpm-run.json`` (the *marker*: run id, the ids of the runs it continues, scene,
start time, the files it writes) into its output folder before anything else, created with
``O_EXCL`` so two runs started at once cannot both claim one folder. A folder *holds a run* when
it has a marker, or (runs of older parmpm versions) a ``summary.json``, a checkpoint or an XDMF
series. The rules:

* the default folder (``parmpm-out/<scene>``, or ``restart_<step>`` beside a checkpoint) is used
  when free, else the first free ``<folder>_2``, ``<folder>_3``, …: repeating a command never
  overwrites the last results;
* an explicit ``--out`` folder that holds another run is refused with one line, unless the user
  passes ``--overwrite``, which deletes that run's outputs (its marker's files, its checkpoints,
  ``summary.json``; files parmpm did not write are kept) before the new run starts;
* a restart is a run of its own: it writes into a folder of its own (by default
  ``restart_<step>`` beside the checkpoint), never into the folder of the run it continues, so
  neither can overwrite or prune the other's checkpoints.

Claiming is also the writability probe: a read-only or missing-permission folder fails here,
before the run, with one line.
"""
from __future__ import annotations

import json
import os
import time
from pathlib import Path

from parmpm.errors import ParmpmError

MARKER = "parmpm-run.json"
#: folders tried after the default one is taken: <folder>_2 ... <folder>_MAX_SUFFIX
MAX_SUFFIX = 999


def read_marker(folder: Path) -> dict | None:
    """The marker of ``folder`` ({} when it is unreadable), or None when there is none."""
    path = Path(folder) / MARKER
    if not path.exists():
        return None
    try:
        marker = json.loads(path.read_text(encoding="utf-8"))
        return marker if isinstance(marker, dict) else {}
    except (OSError, ValueError, UnicodeDecodeError):
        return {}


def _legacy_outputs(folder: Path) -> list[Path]:
    """parmpm outputs in a folder without a marker (runs of older versions)."""
    found = [p for p in (folder / "summary.json",) if p.exists()]
    found += sorted(folder.glob("checkpoint_*.h5"))
    for xdmf in sorted(folder.glob("*.xdmf")):
        found += [xdmf] + [p for p in (xdmf.with_suffix(".h5"), xdmf.with_suffix(".png")) if p.exists()]
    return found


def holds_run(folder: Path) -> bool:
    folder = Path(folder)
    if not folder.is_dir():
        return False
    return read_marker(folder) is not None or bool(_legacy_outputs(folder))


def _describe(folder: Path) -> str:
    marker = read_marker(folder)
    if not marker:
        return "another run's results"
    return (f"the results of another run (scene '{marker.get('scene', '?')}', started "
            f"{marker.get('started', '?')})")


def _remove_run(folder: Path) -> None:
    """``--overwrite``: delete the outputs of the run in ``folder`` (not files parmpm did not write)."""
    marker = read_marker(folder) or {}
    doomed = {folder / name for name in marker.get("files", []) if isinstance(name, str)
              and "/" not in name and name not in ("", ".", "..")}
    doomed.update(_legacy_outputs(folder))
    doomed.update(folder.glob("checkpoint_*.h5.tmp"))
    doomed.add(folder / MARKER)
    for path in sorted(doomed):
        if path.is_file() or path.is_symlink():
            path.unlink()


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


def claim(folder, marker: dict, *, explicit: bool, overwrite: bool = False) -> Path:
    """Claim an output folder for the run described by ``marker`` and return it (rank 0 only).

    ``explicit``: the user named the folder (``--out``), so it is used or refused, never renamed.
    """
    folder = Path(folder)
    marker = dict(marker, started=time.strftime("%Y-%m-%dT%H:%M:%S%z"))
    candidates = [folder] if explicit else \
        [folder] + [folder.with_name(f"{folder.name}_{k}") for k in range(2, MAX_SUFFIX + 1)]
    try:
        for candidate in candidates:
            if candidate.exists() and not candidate.is_dir():
                if explicit:
                    raise ParmpmError(f"output folder '{candidate}' is a file, not a folder")
                continue
            if holds_run(candidate):
                if explicit and overwrite:
                    _remove_run(candidate)
                elif explicit:
                    raise ParmpmError(
                        f"output folder '{candidate}' holds {_describe(candidate)}; choose another "
                        f"--out, or pass --overwrite to delete them and write there")
                else:
                    continue
            try:
                candidate.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise ParmpmError(f"cannot create output folder '{candidate}': "
                                  f"{exc.strerror or exc}") from None
            try:
                _create_marker(candidate, marker, replace=False)
            except FileExistsError:  # another run claimed it this instant
                if explicit:
                    raise ParmpmError(f"output folder '{candidate}' was just claimed by another "
                                      "run; choose another --out") from None
                continue
            return candidate
    except OSError as exc:
        where = exc.filename or folder
        raise ParmpmError(f"cannot write to output folder '{where}': "
                          f"{exc.strerror or exc}") from None
    raise ParmpmError(f"output folders '{folder}' to '{candidates[-1].name}' all hold other runs; "
                      "choose another --out")


def update_marker(folder: Path, **fields) -> None:
    """Add ``fields`` to the marker of a folder this run has claimed (atomic replace)."""
    folder = Path(folder)
    marker = read_marker(folder) or {}
    marker.update(fields)
    _create_marker(folder, marker, replace=True)
