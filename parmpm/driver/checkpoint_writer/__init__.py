"""The parallel strategy behind checkpoints: who writes which rows, and which rows a rank reads
back on restart (the format, the top-level file and the reader are :mod:`parmpm.io.checkpoint`;
docs/checkpoints.md says why).

**Writing** (:func:`write_checkpoint`). Ranks form groups of consecutive ranks
(:func:`parmpm.io.checkpoint.parts.ranks_per_file`: one per rank up to 256 ranks); the lowest rank
of a group, its *lead*, receives the members' rows in blocks of 2^18 (it never holds more than
one block of another rank's rows) and writes them, in rank order and each rank's by (patch, id),
into its part file ``checkpoint_<step>.parts/part_<k>.h5``; rank 0 then writes the top-level
file that binds the parts and holds the patch index (:mod:`~parmpm.driver.checkpoint_writer.groups`).
With one group the rows go into the top-level file itself. Where h5py is built with MPI
(``h5py.get_config().mpi``; PyPI's wheels are not) every rank instead writes its own rows into
one file, collectively (:func:`write_collective`), same schema. Every step is collective and a
problem found by one rank (a full disk at a lead) is raised on every rank with the same one-line
message (:func:`parmpm.core.collective.agree`), so no rank is left waiting; on failure the parts
are removed.

**Reading** (:func:`load_patches`). A version-4 restart deals the patches out from the index's
counts and each rank reads exactly its patches' rows (contiguous ranges of the parts);
:func:`load_rows` reads given rows (versions 1–3, whose rows are global ids, or a restart that
changed the patch grid).
"""
from parmpm.driver.checkpoint_writer.collective import write_collective
from parmpm.driver.checkpoint_writer.read_back import load_patches, load_rows
from parmpm.driver.checkpoint_writer.rows import stored
from parmpm.driver.checkpoint_writer.write import write_checkpoint

__all__ = ["load_patches", "load_rows", "stored", "write_checkpoint", "write_collective"]
