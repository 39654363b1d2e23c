"""Set-up of mesh and particle-file bodies under ``mpirun -n P`` (``tests/mpi/test_listed_share.py``).

For each scene given: :func:`parmpm.scene.agreement.load_shared_scene` and
:func:`parmpm.driver.set_up.set_up`, as ``parmpm run`` does; rank 0 writes every rank's particles
gathered and sorted by global id (``NAME.npz``), and ``report.json``: per scene and rank the
particles it holds, the body files its process read (the readers' caches: a rank that never read
a file holds none), the mesh particles it made from elements (a parallel set-up's share,
:mod:`parmpm.driver.mesh_slices`), the warnings rank 0 logged and the error each rank raised.
"""
import json
import logging
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "harness"))
from mpi_script import run_or_abort  # noqa: E402

from parmpm.particles.store import FLOAT_FIELDS, INT_FIELDS, OPTIONAL_FIELDS  # noqa: E402

READERS = ("_mesh_file", "_mesh", "_particles")


class Lines(logging.Handler):
    def __init__(self):
        super().__init__(logging.WARNING)
        self.lines = []

    def emit(self, record):
        self.lines.append(record.getMessage())


def main() -> None:
    from decomposition import world
    from parmpm.core.errors import ParmpmError
    from parmpm.driver.set_up import set_up
    from parmpm.scene.agreement import load_shared_scene
    from parmpm.scene.body_files import contents

    from parmpm.driver import mesh_slices

    comm = world()
    rank = comm.Get_rank()
    made = []  # the rows of mesh particles this rank made (parmpm.driver.mesh_slices)
    make = mesh_slices.element_particles

    def counted(*args, **kw):
        out = make(*args, **kw)
        made.append(len(out[1]))
        return out

    mesh_slices.element_particles = counted
    out = Path(sys.argv[1])
    lines = Lines()
    logging.getLogger("parmpm").addHandler(lines)
    report = {}
    for path in sys.argv[2:]:
        name = Path(path).stem
        lines.lines.clear()
        made.clear()
        problem, own = None, 0
        try:
            state = set_up(load_shared_scene(comm, path), comm)
            P = state.particles
            own = P.n
            parts = comm.gather({k: getattr(P, k) for k in FLOAT_FIELDS + INT_FIELDS
                                 if k != "patch" and (k in P.optional or k not in OPTIONAL_FIELDS)},
                                root=0)
            if rank == 0:
                order = np.argsort(np.concatenate([p["gid"] for p in parts]), kind="stable")
                np.savez(out / f"{name}.npz", **{k: np.concatenate([p[k] for p in parts])[order]
                                                  for k in parts[0]})
        except ParmpmError as exc:
            problem = f"{type(exc).__name__}: {exc}"
        reads = {r: getattr(contents, r).cache_info().currsize for r in READERS}
        rows = comm.gather({"own": own, "reads": reads, "problem": problem, "made": sum(made)},
                           root=0)
        if rank == 0:
            report[name] = {"ranks": rows, "warnings": list(lines.lines)}
    if rank == 0:
        (out / "report.json").write_text(json.dumps(report, indent=1), encoding="utf-8")


if __name__ == "__main__":
    run_or_abort(main)
