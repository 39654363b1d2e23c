"""What an output folder holds, and what a run may not lose there: the run marker, the files of
a run parmpm wrote (:func:`holds_run`, :func:`doomed`: what ``--overwrite`` deletes), the files
it did not write (:func:`foreign`), and the files a new run reads (:class:`RunInput`), which no
claim deletes or replaces (:func:`check_inputs`). The rules that use them are
:mod:`parmpm.io.run_folder`'s.
"""
from __future__ import annotations

import fnmatch
import json
import os
from pathlib import Path
from typing import NamedTuple

from parmpm.core.errors import ParmpmError
from parmpm.io import run_lock

MARKER = "parmpm-run.json"
#: what parmpm leaves in a folder besides a run's files: the lock, and what a killed run's writers
#: left (removed when a run claims the folder: :func:`parmpm.io.checkpoint.remove_stale_tmp`)
OWN = (run_lock.LOCK, f".{MARKER}.*.tmp", ".scene.toml.tmp", "checkpoint_*.h5.tmp", "*.xdmf.tmp",
       "checkpoint_*.parts")
#: how many names a refusal lists
SHOWN = 3


class RunInput(NamedTuple):
    """A file the run reads (``what``: how a refusal names it, e.g. "the scene file this run
    reads"), which no claim may delete or replace; ``hint``: what the refusal tells the user."""
    path: str | Path
    what: str = "a file this run reads"
    hint: str = "choose another --out"


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


def legacy_outputs(folder: Path) -> list[Path]:
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
    return read_marker(folder) is not None or bool(legacy_outputs(folder))


def foreign(folder: Path) -> list[Path]:
    """What ``folder`` holds that parmpm did not write, when it holds no run: every entry but
    parmpm's lock and temporary files (:data:`OWN`), sorted; [] for a free folder."""
    folder = Path(folder)
    if not folder.is_dir() or holds_run(folder):
        return []
    return sorted(p for p in folder.iterdir()
                  if not any(fnmatch.fnmatchcase(p.name, own) for own in OWN))


def shown(paths) -> str:
    names = [f"'{p.name}/'" if p.is_dir() else f"'{p.name}'" for p in paths]
    more = f" and {len(names) - SHOWN} more" if len(names) > SHOWN else ""
    return ", ".join(names[:SHOWN]) + more


def not_free(folder: Path, found: list[Path], marker: dict) -> ParmpmError:
    files, dirs = writes(folder, marker)
    replaced = [p for p in found if any(p == q for q in files + dirs)]
    keeps = f", replacing {shown(replaced)}" if replaced else " (they are kept)"
    return ParmpmError(f"output folder '{folder}' holds files parmpm did not write "
                       f"({shown(found)}) and no parmpm run; choose another --out, or pass "
                       f"--overwrite to write there{keeps}")


def describe(folder: Path) -> str:
    marker = read_marker(folder)
    if not marker:
        return "another run's results"
    return (f"the results of another run (scene '{marker.get('scene', '?')}', started "
            f"{marker.get('started', '?')})")


def doomed(folder: Path) -> tuple[list[Path], list[Path]]:
    """What ``--overwrite`` deletes in ``folder``: the files (the marker last) and the folders of
    parts of the run there: its marker's files, its checkpoints with their ``.parts``, its
    snapshot series with theirs, the temporary files of its writers. Files parmpm did not write
    are kept."""
    marker = read_marker(folder) or {}
    files = {folder / name for name in marker.get("files", []) if isinstance(name, str)
             and "/" not in name and name not in ("", ".", "..")}
    files.update(legacy_outputs(folder))
    for pattern in ("checkpoint_*.h5.tmp", "*.xdmf.tmp", f".{MARKER}.*.tmp", ".scene.toml.tmp"):
        files.update(folder.glob(pattern))
    dirs = {p.with_suffix(".parts") for p in files if p.suffix in (".h5", ".xdmf")
            and (p.name.startswith("checkpoint_") or p.suffix == ".xdmf")}
    dirs.update(folder.glob("checkpoint_*.parts"))
    files = sorted(p for p in files if p.name != MARKER and (p.is_file() or p.is_symlink()))
    dirs = sorted(d for d in dirs if d.is_dir() and not d.is_symlink())
    return files + ([folder / MARKER] if (folder / MARKER).exists() else []), dirs


def same(a: Path, b: Path) -> bool:
    try:
        return os.path.realpath(a) == os.path.realpath(b) or os.path.samefile(a, b)
    except OSError:
        return False


def writes(folder: Path, marker: dict) -> tuple[list[Path], list[Path]]:
    """The files the new run writes by name (its marker's ``files``) and the ``.parts`` folders
    of its series, which it deletes before its first snapshot."""
    names = [n for n in marker.get("files", []) if isinstance(n, str) and "/" not in n
             and n not in ("", ".", "..")]
    return ([folder / n for n in names],
            [folder / (n[:-len(".xdmf")] + ".parts") for n in names if n.endswith(".xdmf")])


def reads(path: Path) -> list[Path]:
    """What reading ``path`` reads: the file; a series' ``.h5`` for its ``.xdmf``; the
    ``.parts`` folder of a series or checkpoint written in parts."""
    suffix = path.suffix.lower()
    found = [path] + ([path.with_suffix(".h5")] if suffix == ".xdmf" else [])
    return found + ([path.with_suffix(".parts")] if suffix in (".h5", ".xdmf") else [])


def within(path: Path, folder: Path) -> bool:
    return same(path, folder) or os.path.realpath(path).startswith(
        os.path.realpath(folder) + os.sep)


def check_inputs(folder: Path, inputs, marker: dict, held: bool) -> ParmpmError | None:
    """Why claiming ``folder`` would delete (``--overwrite`` of the run it holds, ``held``) or
    replace (a file of the new run's names) a file the run reads, or None."""
    gone, gone_dirs = doomed(folder) if held else ([], [])
    written, written_dirs = writes(folder, marker)
    for item in inputs:
        item = item if isinstance(item, RunInput) else RunInput(item)
        for path in reads(Path(item.path)):
            if any(same(f, path) for f in gone) or any(within(path, d) for d in gone_dirs):
                verb = "--overwrite would delete it"
            elif any(same(f, path) for f in written) or any(within(path, d) for d in written_dirs):
                verb = "the run would replace it"
            else:
                continue
            read = "" if path == Path(item.path) else f", read from '{path.name}'"
            return ParmpmError(f"output folder '{folder}' holds {item.what} ('{item.path}'{read})"
                               f": {verb}; {item.hint}")
    return None
