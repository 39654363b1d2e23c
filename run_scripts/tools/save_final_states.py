"""Run scenes under ``mpirun -n P`` and save each final particle state (for rank-count
comparisons: ``tests/mpi/test_mpi_ranks.py``, ``bit_identical.py``).

    mpirun -n 3 python run_scripts/tools/save_final_states.py OUT_DIR CASES_JSON

``CASES_JSON`` maps a case name to ``[scene, [overrides...]]``. For each case, rank 0 writes
``OUT_DIR/<case>.npz`` holding gid, x, v, F, stress, damage (and cpdi2's corners, a plastic run's state rows; global-id
order) and the summary as JSON.
"""
import json
import sys
from pathlib import Path

import numpy as np

from decomposition import world
from parmpm.core.log import setup_logging
from parmpm.scene.load import load_scene
from parmpm.driver.simulation import Simulation
from parmpm.driver.warm_up import compile_first


def main() -> None:
    out, cases = Path(sys.argv[1]), json.loads(Path(sys.argv[2]).read_text())
    comm = world()
    setup_logging(comm.Get_rank(), comm.Get_size(), quiet=True)
    for name, (scene, overrides) in cases.items():
        sim = Simulation(load_scene(scene, overrides), out / name, quiet=True, comm=comm,
                         warm_up=compile_first)
        summary = sim.run()
        P = sim.particles
        fields = {"gid": P.gid, "x": P.x, "v": P.v, "F": P.F, "stress": P.stress,
                  "damage": P.damage}
        if "corners" in P.optional:  # cpdi2's tracked corners
            fields["corners"] = P.corners
        if "plastic" in P.optional:  # a plastic material's state rows
            fields["plastic"] = P.plastic
        g = sim.gather(fields)
        if comm.Get_rank() == 0:
            np.savez(out / f"{name}.npz", summary=json.dumps(summary), **g)


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run_scripts/: study.py
    from study import main_guard

    main_guard(main)
