"""Writing a checkpoint (collective): the rows laid out in rank order, then written by writer
groups, or by every rank into one file where h5py has MPI."""
from __future__ import annotations

from pathlib import Path

from parmpm.core.errors import ParmpmError
from parmpm.driver.checkpoint_writer.collective import mpio, write_collective
from parmpm.driver.checkpoint_writer.groups import write_in_groups
from parmpm.driver.checkpoint_writer.rows import rank_order, stored
from parmpm.io.checkpoint.parts import layout_record
from parmpm.particles.store import Particles


def write_checkpoint(comm, P: Particles, path: Path, n_total: int, attrs: dict, keep: int,
                     lineage: str, disc, ranks_per_file_setting="auto") -> Path:
    """Write ``path`` (collective): atomic (parts first, the top-level file last); then delete
    all but the newest ``keep`` checkpoints of this run (``lineage``) in its folder, with their
    parts. ``disc``: the run's :class:`parmpm.transfer.discretisation.Discretisation` (its patch grid is
    what the index refers to). Every rank returns or raises the same."""
    path = Path(path)
    order, all_patches, first, index = rank_order(comm, P, disc.layout.n_patches)
    like = {k: getattr(P, k)[:0] for k in stored(P)}
    top = {**attrs, "layout": layout_record(disc)}
    if lineage is not None:
        top["lineage"] = lineage
    if int(first[-1]) != n_total:  # the same on every rank
        raise ParmpmError(f"cannot write checkpoint '{path}': the ranks hold {int(first[-1])} "
                          f"particles, not {n_total}")
    if mpio(comm):
        return write_collective(comm, P, order, path, top, like, all_patches, first, index,
                                keep, lineage, driver="mpio")
    return write_in_groups(comm, P, order, path, top, like, all_patches, first, index, keep,
                           lineage, ranks_per_file_setting)
