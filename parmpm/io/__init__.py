"""Output: summary.json, XDMF particle snapshots (meshio/h5py), PNG figures (matplotlib).

meshio, h5py and matplotlib are imported only when a writer or a figure is used, so the solver
runs without them.
"""

from parmpm.io.figures import plot_particles
from parmpm.io.summary import format_summary, to_jsonable, write_summary
from parmpm.io.xdmf import SnapshotWriter, pad_point_data

__all__ = [
    "SnapshotWriter",
    "format_summary",
    "pad_point_data",
    "plot_particles",
    "to_jsonable",
    "write_summary",
]
