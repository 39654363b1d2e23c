"""A checkpoint written by writer groups: each group's lead gathers its members' rows, in blocks,
into its part file (one group: into the top-level file itself), and rank 0 binds the parts in
the top-level file. Every step ends in an agreement, so a problem at one rank (a full disk at a
lead) is raised on every rank and no rank is left waiting; on failure the parts are removed."""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

import parmpm.io.checkpoint.space as space
from parmpm.core.collective import agree
from parmpm.core.errors import ParmpmError
from parmpm.driver.checkpoint_writer.rows import BLOCK
from parmpm.io.checkpoint.cleanup import prune, remove_checkpoint
from parmpm.io.checkpoint.format import BLOCK_ROWS, DTYPES, FORMAT, PART_FORMAT, segments_of
from parmpm.io.checkpoint.parts import ranks_per_file, top_tables, write_top
from parmpm.io.checkpoint.paths import part_name, parts_folder
from parmpm.io.checkpoint.writer import CheckpointWriter
from parmpm.io.guarded_file import space_message

_TAG = 0x5EC7


def write_in_groups(comm, P, order, path: Path, top: dict, like: dict, all_patches, first, index,
                    keep: int, lineage: str | None, setting="auto") -> Path:
    """Write ``path`` by writer groups of ``ranks_per_file(size, setting)`` ranks (collective;
    the arguments as :func:`parmpm.driver.checkpoint_writer.collective.write_collective` takes
    them), then prune this run's older checkpoints."""
    g = _Groups(comm, path, top, like, all_patches, first, index, setting)
    rank = comm.Get_rank()
    problem = g.prepare() if rank == 0 else None
    agree(comm, problem)
    writer = None
    if rank == g.lead:
        writer, problem = g.open_part(lineage)
    problem = g.stream(P, order, writer, problem)
    problem, digest = g.commit_part(writer, problem)
    results = comm.gather((problem, digest), root=0)
    if rank == 0:
        problem = g.bind(results, keep, lineage)
    agree(comm, problem)
    return path


class _Groups:
    """One checkpoint written by groups: who leads which part, and each step of the writing."""

    def __init__(self, comm, path: Path, top: dict, like: dict, all_patches, first, index,
                 setting):
        rank, size = comm.Get_rank(), comm.Get_size()
        self.comm, self.path, self.like = comm, path, like
        self.all_patches, self.first, self.index = all_patches, first, index
        self.n_total = int(first[-1])
        self.rpf = ranks_per_file(size, setting)
        self.n_parts = -(-size // self.rpf)
        self.top = {**top, "part_files": self.n_parts, "ranks_per_file": self.rpf}
        self.lead, self.part = rank - rank % self.rpf, rank // self.rpf
        self.members = range(self.lead, min(self.lead + self.rpf, size))
        self.inline = self.n_parts == 1
        self.folder = parts_folder(path)

    def prepare(self) -> str | None:
        """Rank 0, before any rank writes: the space all files need, a clean parts folder (a
        checkpoint of the same step in this folder is replaced). Returns a problem or None."""
        segs = sum(int(np.sum(-(-np.asarray(c, np.int64) // BLOCK_ROWS)))
                   for _, c in self.all_patches)
        need = space.estimate_bytes(self.n_total, self.like, self.top, segments=segs,
                                    extra=self.index.nbytes)
        if not self.inline:  # each part's own overhead
            need += space.estimate_bytes(0, self.like, {}) * len(self.all_patches)
        try:
            free = space.free_bytes(self.path.parent)
            if need > free:
                return space_message(self.path, need, free)
            if self.path.exists() or self.folder.exists():
                remove_checkpoint(self.path)
            if not self.inline:
                self.folder.mkdir()
        except OSError as exc:
            return space.os_problem(self.path, exc)
        return None

    def open_part(self, lineage: str | None):
        """The lead's writer of its group's rows: its part, or the checkpoint itself when there
        is one group. Returns (writer, problem)."""
        seg = segments_of(np.concatenate([self.all_patches[r][1] for r in self.members] + [[]]))
        rows = int(self.first[self.members[-1] + 1] - self.first[self.lead])
        try:
            if self.inline:
                return CheckpointWriter(self.path, rows, self.like, self.top, segments=seg,
                                        fmt=FORMAT, extra_bytes=self.index.nbytes + 256), None
            attrs = {"part": self.part, "parts": self.n_parts, "first_row": int(self.first[self.lead]),
                     "rows": rows, "step": self.top["step"], "lineage": lineage or ""}
            return CheckpointWriter(self.folder / part_name(self.part), rows, self.like, attrs,
                                    segments=seg, fmt=PART_FORMAT), None
        except ParmpmError as exc:
            return None, str(exc)

    def stream(self, P, order: np.ndarray, writer, problem):
        """Members send their rows (rank order, by patch and id) to the lead in blocks; the lead
        writes them (and, after a problem, still receives them, so no member waits)."""
        comm, lead = self.comm, self.lead
        rank = comm.Get_rank()
        if rank != lead:
            for a in range(0, P.n, BLOCK):
                idx = order[a:a + BLOCK]
                for k in self.like:
                    comm.Send(np.ascontiguousarray(getattr(P, k)[idx], dtype=DTYPES[k]),
                              dest=lead, tag=_TAG)
            return problem
        lo = 0
        for r in self.members:
            n_r = int(self.first[r + 1] - self.first[r])
            for a in range(0, n_r, BLOCK):
                m = min(BLOCK, n_r - a)
                block = (self._own(P, order[a:a + m]) if r == rank else self._receive(P, r, m))
                if problem is None:
                    try:
                        writer.write(lo, block)
                    except ParmpmError as exc:
                        problem = str(exc)
                lo += m
        return problem

    def _own(self, P, idx: np.ndarray) -> dict:
        return {k: getattr(P, k)[idx] for k in self.like}

    def _receive(self, P, source: int, m: int) -> dict:
        block = {}
        for k in self.like:
            block[k] = np.empty((m,) + getattr(P, k).shape[1:], DTYPES[k])
            self.comm.Recv(block[k], source=source, tag=_TAG)
        return block

    def commit_part(self, writer, problem):
        """The lead commits its file (with one group, the index and part table go in it) or,
        after a problem, throws it away. Returns (problem, the file's digest)."""
        if writer is None:
            return problem, None
        try:
            if problem is None:
                extra = (top_tables(self.index, np.array([0, self.n_total]), [(".", "")])
                         if self.inline else None)
                return None, writer.commit(extra)
            writer.abort()
        except ParmpmError as exc:
            problem = str(exc)
        return problem, None

    def bind(self, results, keep: int, lineage: str | None) -> str | None:
        """Rank 0, every part committed (``results``: each rank's (problem, digest)): write the
        top-level file over the parts and prune; on a problem, remove the parts. Returns the
        first problem or None."""
        problem = next((p for p, _ in results if p), None)
        try:
            if problem is None and not self.inline:
                self._write_top(results)
            if problem is None:
                prune(self.path.parent, keep, lineage=lineage)
        except ParmpmError as exc:
            problem = str(exc)
        except OSError as exc:
            problem = f"cannot write checkpoint '{self.path}': {exc}"
        if problem is not None and not self.inline:
            shutil.rmtree(self.folder, ignore_errors=True)
        return problem

    def _write_top(self, results) -> None:
        size, rpf = len(results), self.rpf
        files = [(f"{self.folder.name}/{part_name(k)}", results[k * rpf][1])
                 for k in range(self.n_parts)]
        bounds = self.first[[min(k * rpf, size) for k in range(self.n_parts + 1)]]
        write_top(self.path, self.top, self.like,
                  [(f, int(bounds[k]), int(bounds[k + 1] - bounds[k])) for k, (f, _) in enumerate(files)],
                  self.n_total, top_tables(self.index, bounds, files))
