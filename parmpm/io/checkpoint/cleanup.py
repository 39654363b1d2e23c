"""Which files are whose: a checkpoint's lineage (the run that wrote it), removing a checkpoint
with its parts, keeping the newest few of one run, and clearing what an interrupted writer left.

A folder may hold checkpoints another run wrote: only the files of this run's lineage are ever
pruned, and a file that cannot be read is nobody's to delete.
"""
from __future__ import annotations

import shutil
from pathlib import Path

from parmpm.io.checkpoint.format import FORMAT
from parmpm.io.checkpoint.paths import parts_folder


def read_lineage(path: Path) -> str | None:
    """The ``lineage`` attribute of a checkpoint, cheaply (one attribute; no checks); None when
    it has none. Raises OSError (or h5py's errors) for an unreadable file."""
    import h5py

    with h5py.File(path, "r") as f:
        if f.attrs.get("format") != FORMAT:
            raise OSError(f"'{path}' is not a parmpm checkpoint")
        v = f.attrs.get("lineage")
        return None if v is None else str(v)


def remove_checkpoint(path: Path) -> None:
    """Delete checkpoint ``path`` and its part files (the top-level file first, so that a kill
    meanwhile leaves stale parts, which :func:`remove_stale_tmp` clears, never a checkpoint
    without them)."""
    Path(path).unlink(missing_ok=True)
    shutil.rmtree(parts_folder(path), ignore_errors=True)


def prune(folder: Path, keep: int, lineage: str | None = None) -> list[Path]:
    """Delete all but the newest ``keep`` checkpoints (by step) of ``lineage`` in ``folder``,
    with their parts; ``lineage=None`` means the checkpoints that carry no lineage. Files of
    another lineage, and files that cannot be read, are never deleted. Returns the deleted
    paths (the top-level files)."""
    if keep <= 0:
        return []
    mine = []
    for p in sorted(Path(folder).glob("checkpoint_*.h5")):
        try:
            if read_lineage(p) == lineage:
                mine.append(p)
        except Exception:  # noqa: BLE001 - unreadable: not ours to delete
            continue
    gone = []
    for old in mine[:-keep]:
        if old.exists():
            remove_checkpoint(old)
            gone.append(old)
    return gone


def remove_stale_tmp(folder: Path) -> list[Path]:
    """Delete what an interrupted writer left in ``folder``: temporary checkpoints
    (``checkpoint_*.h5.tmp``) and snapshot indexes (``*.xdmf.tmp``), part folders whose
    checkpoint was never committed (``checkpoint_<step>.parts`` without ``checkpoint_<step>.h5``)
    and temporary parts. Returns them."""
    gone = []
    folder = Path(folder)
    if not folder.is_dir():
        return gone
    for pattern in ("checkpoint_*.h5.tmp", "*.xdmf.tmp"):
        for p in sorted(folder.glob(pattern)):
            if p.is_file() and not p.is_symlink():
                p.unlink(missing_ok=True)
                gone.append(p)
    for d in sorted(folder.glob("checkpoint_*.parts")):
        if not d.is_dir() or d.is_symlink():
            continue
        if not d.with_name(d.name[:-len(".parts")] + ".h5").exists():
            shutil.rmtree(d, ignore_errors=True)
            gone.append(d)
            continue
        for p in sorted(d.glob("part_*.h5.tmp")):
            p.unlink(missing_ok=True)
            gone.append(p)
    return gone
