"""Particle snapshots: XDMF 3 XML + HDF5 (h5py), for ParaView, VTK, meshio and plain numpy.

``<name>.h5`` (next to ``<name>.xdmf``) holds one group per snapshot, named by the run's step::

    /                           attrs: format, format_version, dim, fields (JSON: units, description)
    /step_00000120/             attrs: time, step, index (0, 1, ... in the order written)
        x             (N, 3)    positions, zero-padded to 3 columns (the XDMF geometry)
        velocity      (N, 3)    per-axis vectors padded to 3 columns (a scalar in 1D)
        stress, F     (N, 9)    tensors, row-major 3×3, zero-padded (a scalar in 1D)
        volume, ...   (N,)      scalars; integer ids stay integers (gid int64, rank int32)
        domains       (N·c, 3)  the c corners of every particle's domain, in VTK/XDMF node order
    /connectivity/<cell>_<N>    (N, c) int64: node numbers of the cells (shared by every step)
    /history/<column>           the run's history table (:meth:`SnapshotWriter.write_table`)

Every dataset carries ``units``, ``description`` and ``shape`` (the per-particle shape before
padding, which :func:`parmpm.io.xdmf.reader.load_snapshots` restores). Fields are whatever
the caller hands :meth:`SnapshotWriter.write`; a run's are :mod:`parmpm.driver.snapshot_fields`.

The XML index (``<name>.xdmf``) holds two temporal collections under one ``Domain``, so ParaView
shows two blocks: ``domains`` (one uniform grid per snapshot: the domains as cells — ``Polyline``
of 2 nodes in 1D, ``Quadrilateral`` in 2D, ``Hexahedron`` in 3D — carrying every particle field
as cell data, by reference to the same datasets) and ``particles`` (one uniform grid per
snapshot: a ``Polyvertex`` cell per particle, its own geometry, the fields as point data).
Every grid has its own geometry, so readers that follow XDMF (ParaView, VTK's
``vtkXdmfReader``/``vtkXdmf3Reader``) see the points move. The particle collection is the last
grid of the domain, which is what meshio's ``TimeSeriesReader`` reads: ``read_data(k)`` gives
snapshot ``k``'s time and point data (positions included, as the point field ``x``); its
``read_points_cells()`` reads one geometry (the first snapshot's) for all steps — meshio's time
series are fixed meshes, so take positions from ``x``. ``meshio.read`` reads only files of one
grid: on any time series (this one included) it prints meshio's ``ReadError`` ("Only supports
one grid") and exits the interpreter; :meth:`parmpm.io.Snapshots.to_meshio` gives one snapshot
as a ``meshio.Mesh`` instead.

Parts
-----
Under MPI with several writer groups (the checkpoints' rule,
:func:`parmpm.io.checkpoint.parts.ranks_per_file`: one group per rank up to 256 ranks), each
group's lead writes its members' particles, in gid order, into its own part
(``SnapshotWriter(..., part=k)``)::

    <name>.xdmf                 the index (rank 0)
    <name>.h5                   attrs as above, format_version 2, parts (JSON: the part files);
                                /step_<step>/ (attrs time, step, index, rows: each part's rows),
                                /history/<column>; no particles
    <name>.parts/part_<k>.h5    the single-file layout above for part k's particles (attr part)

Each step of each temporal collection is then a *spatial* collection (``GridType="Collection"
CollectionType="Spatial"``) of one uniform grid per part that holds particles, pointing at that
part's datasets by relative name (``<name>.parts/part_00003.h5:/step_00000120/x``). A part
flushes its snapshot before it reports; rank 0 indexes a step (:meth:`SnapshotWriter.add`) only
when every lead reported it written, so the index lists no step with a missing part. VTK's XDMF
reader (ParaView) reads the series as one: each time step a multiblock of the parts, N points
in all. meshio's ``TimeSeriesReader`` wants a uniform grid per step: on a series in parts it
raises ``meshio.ReadError("Couldn't find the mesh grid")`` when opened; read such a series with
:func:`parmpm.io.load_snapshots` (which merges the parts by gid) and ``to_meshio``. One writer
(one rank, or every rank in one group) writes the single-file layout, format_version 1.

Without parts, call from one rank with the particle state of all ranks in gid order; the run's
collective side is :class:`parmpm.driver.run_files.RunFiles`. One concept a module:
:mod:`~parmpm.io.xdmf.layout` (fields shaped for XDMF, the XML elements that point at the
datasets), :mod:`~parmpm.io.xdmf.index` (the XML index, kept on disk),
:mod:`~parmpm.io.xdmf.writer` (:class:`SnapshotWriter`), :mod:`~parmpm.io.xdmf.reader`
(:func:`load_snapshots`).
"""
from parmpm.io.xdmf.layout import (FORMAT, FORMAT_VERSION, PARTS_VERSION, pad_point_data,
                                   part_file, xdmf_cells)
from parmpm.io.xdmf.reader import Snapshots, load_snapshots
from parmpm.io.xdmf.writer import METADATA_CACHE, SnapshotWriter, bound_metadata_cache

__all__ = ["FORMAT", "FORMAT_VERSION", "METADATA_CACHE", "PARTS_VERSION", "SnapshotWriter",
           "Snapshots", "bound_metadata_cache", "load_snapshots", "pad_point_data", "part_file",
           "xdmf_cells"]
