"""HDF5 checkpoints, the format: what a file of particle rows holds, how it is checked, how it is
written atomically, and which files belong to which checkpoint (docs/checkpoints.md says why).

A checkpoint ``checkpoint_<step>.h5`` is one file to h5py, ParaView and ``parmpm restart``: its
``particles/<field>`` datasets hold every particle. Since version 4 the rows are in *rank order*
(the ranks that wrote it in turn, each rank's rows sorted by patch, then global id; the ``gid``
column says which particle a row is), and ``index/patch_rows`` says where each patch's rows lie,
so a restart reads exactly the rows of its own patches. With more than one writer the rows live
in part files, ``checkpoint_<step>.parts/part_<k>.h5``, that the top-level file binds with HDF5
virtual datasets (relative source names: the folder can be moved); with one writer they are in
the top-level file itself. :mod:`parmpm.driver.checkpoint_writer` is the parallel strategy.

One concept a module: :mod:`~parmpm.io.checkpoint.format` (names, fields, versions, segments),
:mod:`~parmpm.io.checkpoint.digests` (integrity), :mod:`~parmpm.io.checkpoint.space` (sizes
and free space), :mod:`~parmpm.io.checkpoint.writer` (one file, atomically),
:mod:`~parmpm.io.checkpoint.parts` (the top-level file of parts),
:mod:`~parmpm.io.checkpoint.paths` (file names; parts stay in their folder),
:mod:`~parmpm.io.checkpoint.cleanup` (lineage, pruning, stale files),
:mod:`~parmpm.io.checkpoint.data_file` and :mod:`~parmpm.io.checkpoint.reader` (reading back).
"""
from parmpm.io.checkpoint.cleanup import prune, read_lineage, remove_checkpoint, remove_stale_tmp
from parmpm.io.checkpoint.digests import arrays_digest, attrs_digest, block_digest, tables_digest
from parmpm.io.checkpoint.format import (ATTRS, BLOCK_ROWS, DTYPES, FIELDS, FORMAT, OPTIONAL,
                                         PART_FORMAT, VERSION, required_fields, segments_of)
from parmpm.io.checkpoint.parts import MAX_PARTS, ranks_per_file
from parmpm.io.checkpoint.paths import checkpoint_name, part_name, parts_folder
from parmpm.io.checkpoint.reader import CheckpointReader
from parmpm.io.checkpoint.space import estimate_bytes
from parmpm.io.checkpoint.writer import CheckpointWriter
from parmpm.io.guarded_file import space_message

__all__ = [
    "ATTRS", "BLOCK_ROWS", "DTYPES", "FIELDS", "FORMAT", "MAX_PARTS", "OPTIONAL", "PART_FORMAT",
    "VERSION", "CheckpointReader", "CheckpointWriter", "arrays_digest", "attrs_digest",
    "block_digest", "checkpoint_name", "estimate_bytes", "part_name", "parts_folder", "prune",
    "ranks_per_file", "read_lineage", "remove_checkpoint", "remove_stale_tmp", "required_fields",
    "segments_of", "space_message", "tables_digest",
]
