"""The files of one run: its claimed folder, resolved scene, snapshot series, summary and figure.

Rank 0 writes every shared file; each call is collective, and a problem that rank 0 meets (a full
disk, an unwritable folder, another run's folder) is raised on every rank with the same one-line
message (:func:`parmpm.collective.agree`), so no rank is left waiting in a collective and
``mpirun`` prints it once. The folder rules are :mod:`parmpm.io.run_folder`'s.
"""
from __future__ import annotations

from pathlib import Path

from parmpm.collective import agree
from parmpm.errors import ParmpmError
from parmpm.io.checkpoint import remove_stale_tmp
from parmpm.io.run_folder import claim
from parmpm.io.summary import write_summary
from parmpm.io.xdmf import SnapshotWriter
from parmpm.log import get_logger
from parmpm.snapshot_fields import field_info

log = get_logger(__name__)

SCENE_NAME = "scene.toml"


def _one_line(exc: Exception, what: str) -> str:
    if isinstance(exc, ParmpmError):
        return str(exc)
    return f"cannot write {what}: {getattr(exc, 'strerror', None) or exc}"


class RunFiles:
    """Where a run writes (``folder``), and its writes, collectively."""

    def __init__(self, comm, folder: Path, explicit: bool, overwrite: bool):
        self.comm = comm
        self.root = comm.Get_rank() == 0
        self.folder = Path(folder)
        self.explicit, self.overwrite = explicit, overwrite
        self.snapshots = None

    def claim(self, marker: dict) -> Path:
        """Claim the output folder before anything is written (a folder that cannot be written
        or holds another run fails here) and clear temporary files a killed run left."""
        folder, problem = None, None
        if self.root:
            try:
                folder = claim(self.folder, marker, explicit=self.explicit,
                               overwrite=self.overwrite)
                if folder != self.folder:
                    log.info("%s holds another run: writing to %s", self.folder, folder)
                remove_stale_tmp(folder)
            except (ParmpmError, OSError) as exc:
                problem = _one_line(exc, f"to output folder '{self.folder}'")
        folder = self.comm.bcast(folder, root=0)
        agree(self.comm, problem)
        self.folder = folder
        return folder

    def open_snapshots(self, series: str, dim: int) -> None:
        problem = None
        if self.root:
            try:
                self.snapshots = SnapshotWriter(self.folder, series, dim, fields=field_info(dim))
            except (ParmpmError, OSError) as exc:
                problem = _one_line(exc, f"snapshots to '{self.folder}'")
        agree(self.comm, problem)

    def write_snapshot(self, t: float, gathered: dict | None) -> None:
        """``gathered``: the particle fields on rank 0 (:func:`parmpm.snapshot_fields.snapshot_fields`:
        with ``x``, and optionally ``domains`` and ``step``), None elsewhere."""
        problem = None
        if self.snapshots is not None and gathered is not None:
            try:
                x, step = gathered.pop("x"), gathered.pop("step", None)
                domains = gathered.pop("domains", None)
                self.snapshots.write(t, x, gathered, step=step, domains=domains)
            except (ParmpmError, OSError) as exc:
                problem = _one_line(exc, f"snapshot to '{self.folder}'")
        agree(self.comm, problem)

    def close_snapshots(self) -> str | None:
        """Close the series (rank 0); never raises (a failing run's own error must win): the
        problem is returned, for :func:`agree` on the normal path."""
        writer, self.snapshots = self.snapshots, None
        if writer is None:
            return None
        try:
            writer.close()
        except (ParmpmError, OSError) as exc:
            return _one_line(exc, f"snapshots to '{self.folder}'")
        return None

    def write_scene(self, text: str) -> None:
        """``scene.toml``: the resolved scene, as a file ``parmpm run`` takes (rank 0)."""
        problem = None
        if self.root:
            path = self.folder / SCENE_NAME
            try:
                tmp = path.with_name(f".{SCENE_NAME}.tmp")
                tmp.write_text(text, encoding="utf-8")
                tmp.replace(path)
            except OSError as exc:
                problem = _one_line(exc, f"'{path}'")
        agree(self.comm, problem)

    def write_summary(self, summary: dict) -> None:
        problem = None
        if self.root:
            try:
                write_summary(self.folder, summary)
            except (ParmpmError, OSError) as exc:
                problem = _one_line(exc, f"'{self.folder / 'summary.json'}'")
        agree(self.comm, problem)

    def write_figure(self, name: str, gathered: dict | None, dim: int, title: str) -> None:
        """The final-state figure (rank 0); a failure is a warning, not the run's end."""
        if not self.root or gathered is None:
            return
        from parmpm.io.figures import plot_particles

        try:
            plot_particles(self.folder / f"{name}.png", gathered["x"], gathered["stretch"], dim,
                           corners=gathered.get("corners"), title=title)
        except OSError as exc:
            log.warning("no figure: cannot write to %s: %s", self.folder, exc.strerror or exc)
