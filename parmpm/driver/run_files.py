"""The files of one run: its claimed folder, resolved scene, snapshot series, summary and figure.

Rank 0 writes every shared file, except snapshots written in parts (each writer group's lead
writes its own part: :meth:`RunFiles.open_snapshots`); each call is collective, and a problem
that a writer meets (a full disk, an unwritable folder, another run's folder) is raised on every
rank with the same one-line message (:func:`parmpm.core.collective.agree`), so no rank is left waiting in a collective and
``mpirun`` prints it once. The folder rules are :mod:`parmpm.io.run_folder`'s.
"""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

from parmpm.core.collective import agree
from parmpm.core.errors import ParmpmError
from parmpm.io.checkpoint import ranks_per_file as group_size
from parmpm.io.checkpoint import remove_stale_tmp
from parmpm.io.run_folder import RunInput, claim
from parmpm.io.summary import write_summary
from parmpm.io.xdmf import SnapshotWriter
from parmpm.core.log import get_logger
from parmpm.driver.snapshot_fields import field_info
from parmpm.scene.body_files import files_read

log = get_logger(__name__)

SCENE_NAME = "scene.toml"
#: a restart whose --out holds its checkpoint: where it can write instead
RESTART_HINT = ("restart into another --out (without --out: a folder of its own beside the "
                "checkpoint)")


def run_inputs(scene, continues: dict | None) -> list[RunInput]:
    """The files a run reads, which claiming its folder never deletes or replaces: a restart's
    checkpoint (first: a restart's scene is read from it too), the scene file, the bodies'
    files (a restart reads none, but its checkpoints and ``scene.toml`` name them)."""
    found = [RunInput(continues["checkpoint"], "the checkpoint this restart continues from",
                      RESTART_HINT)] if continues else []
    return found + [RunInput(path, what) for path, what in files_read(scene)]


def _one_line(exc: Exception, what: str) -> str:
    if isinstance(exc, ParmpmError):
        return str(exc)
    return f"cannot write {what}: {getattr(exc, 'strerror', None) or exc}"


def _by_gid(members: list[dict]) -> dict:
    """The fields of a writer group's members as one, in global-id order."""
    out = {k: np.concatenate([m[k] for m in members]) for k in members[0]}
    order = np.argsort(out["gid"], kind="stable")
    return {k: v[order] for k, v in out.items()}


class RunFiles:
    """Where a run writes (``folder``), and its writes, collectively."""

    def __init__(self, comm, folder: Path, explicit: bool, overwrite: bool, inputs=()):
        self.comm = comm
        self.root = comm.Get_rank() == 0
        self.folder = Path(folder)
        self.explicit, self.overwrite = explicit, overwrite
        self.inputs = tuple(inputs)  # what the run starts from: --overwrite never deletes it
        self._claim = None  # rank 0's claim of the folder (its lock: the run is alive)
        self.snapshots = None  # rank 0's series writer (the index, the history table)
        self._part = None  # a group lead's part writer (a series in parts)
        self.n_parts, self._group = 1, comm

    def claim(self, marker: dict) -> Path:
        """Claim the output folder before anything is written (a folder that cannot be written
        or holds another run fails here) and clear temporary files a killed run left. Rank 0
        holds the claim's lock until :meth:`release`."""
        folder, problem = None, None
        if self.root:
            try:
                self._claim = claim(self.folder, marker, explicit=self.explicit,
                                    overwrite=self.overwrite, inputs=self.inputs)
                folder = self._claim.folder
                if folder != self.folder:
                    log.info("%s holds another run or files parmpm did not write: writing to %s",
                             self.folder, folder)
                remove_stale_tmp(folder)
            except (ParmpmError, OSError) as exc:
                problem = _one_line(exc, f"to output folder '{self.folder}'")
        folder = self.comm.bcast(folder, root=0)
        agree(self.comm, problem)
        self.folder = folder
        return folder

    def release(self) -> None:
        """The run is over (ended, failed or interrupted): the marker says so and rank 0 drops
        the lock; never raises, never communicates."""
        held, self._claim = self._claim, None
        if held is not None:
            held.release()

    def open_snapshots(self, series: str, dim: int, ranks_per_file="auto",
                       plastic: bool = False) -> None:
        """Open the snapshot series (collective). The ranks form writer groups by the
        checkpoints' rule (:func:`parmpm.io.checkpoint.parts.ranks_per_file`); with one group
        rank 0 writes ``<series>.xdmf`` and ``<series>.h5`` as ever, with several each group's
        lead writes ``<series>.parts/part_<k>.h5`` and rank 0 also the index
        (:mod:`parmpm.io.xdmf`, "Parts")."""
        size, rank = self.comm.Get_size(), self.comm.Get_rank()
        per = group_size(size, ranks_per_file)
        self.n_parts = -(-size // per)
        self._group = self.comm if self.n_parts == 1 else self.comm.Split(rank // per, rank)
        fields = field_info(dim, plastic)
        problem = None
        if self.root:
            try:
                stale = self.folder / f"{series}.parts"  # of a run this one overwrites
                if stale.is_dir() and not stale.is_symlink():
                    shutil.rmtree(stale)
                self.snapshots = SnapshotWriter(self.folder, series, dim, fields=fields,
                                                parts=self.n_parts if self.n_parts > 1 else None)
            except (ParmpmError, OSError) as exc:
                problem = _one_line(exc, f"snapshots to '{self.folder}'")
        agree(self.comm, problem)
        if self.n_parts == 1:
            return
        problem = None
        if rank % per == 0:
            try:
                self._part = SnapshotWriter(self.folder, series, dim, fields=fields,
                                            part=rank // per)
            except (ParmpmError, OSError) as exc:
                problem = _one_line(exc, f"snapshots to '{self.folder}'")
        try:
            agree(self.comm, problem, root=None)
        except ParmpmError:
            self.close_snapshots()
            raise

    def write_snapshot(self, t: float, fields: dict) -> None:
        """``fields``: this rank's particles (:func:`parmpm.driver.snapshot_fields.snapshot_fields`:
        with ``x``, ``gid``, and optionally ``domains`` and ``step``). Collective: gathered to the
        group's lead in global-id order and written; with parts, rank 0 indexes the snapshot
        once every lead reported its part written and flushed, and a failure on any rank is the
        same one line on every rank."""
        fields = dict(fields)
        step = fields.pop("step", None)
        members = self._group.gather(fields, root=0)
        writer = self._part if self.n_parts > 1 else self.snapshots
        problem, record = None, None
        if members is not None and writer is not None:
            try:
                merged = _by_gid(members)
                x, domains = merged.pop("x"), merged.pop("domains", None)
                record = writer.write(t, x, merged, step=step, domains=domains)
            except (ParmpmError, OSError) as exc:
                problem = _one_line(exc, f"snapshot to '{self.folder}'")
        if self.n_parts == 1:
            agree(self.comm, problem)
            return
        reports = self.comm.gather((self.comm.Get_rank(), problem, record), root=0)
        problem = None
        if self.root:
            failed = [p for _, p, _ in reports if p]
            if failed:  # the lowest rank's
                problem = failed[0]
            elif self.snapshots is not None:
                try:
                    self.snapshots.add([r for _, _, r in reports if r is not None])
                except (ParmpmError, OSError) as exc:
                    problem = _one_line(exc, f"snapshot to '{self.folder}'")
        agree(self.comm, problem)

    def close_snapshots(self) -> str | None:
        """Close the series (every writer); never raises and never communicates (a failing
        run's own error must win): rank 0's problem is returned, for :func:`agree` on the
        normal path; a lead's problem closing its part is logged (its snapshots were flushed
        when written)."""
        problem = None
        part, self._part = self._part, None
        if part is not None:
            try:
                part.close()
            except (ParmpmError, OSError) as exc:
                problem = _one_line(exc, f"snapshots to '{self.folder}'")
                if not self.root:
                    log.warning("%s", problem)
        writer, self.snapshots = self.snapshots, None
        if writer is not None:
            try:
                writer.close()
            except (ParmpmError, OSError) as exc:
                problem = problem or _one_line(exc, f"snapshots to '{self.folder}'")
        return problem if self.root else None

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
