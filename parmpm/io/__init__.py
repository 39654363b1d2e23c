"""Output: summary.json, particle snapshots (XDMF + HDF5 with h5py, one file or one part per
writer group under MPI; read back with :func:`load_snapshots`), PNG figures (matplotlib).

h5py, meshio and matplotlib are imported only when a writer, a reader or a figure is used, so
the solver runs without them.
"""

from parmpm.io.figures import plot_particles
from parmpm.io.summary import format_summary, to_jsonable, write_summary
from parmpm.io.xdmf import SnapshotWriter, Snapshots, load_snapshots, pad_point_data

__all__ = [
    "SnapshotWriter",
    "Snapshots",
    "format_summary",
    "load_snapshots",
    "pad_point_data",
    "plot_particles",
    "to_jsonable",
    "write_summary",
]
