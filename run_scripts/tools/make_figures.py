"""Regenerate every documentation figure: run each study in full mode, one after the other.

    python run_scripts/tools/make_figures.py                 # all studies, one rank each
    python run_scripts/tools/make_figures.py --np 2          # each under mpirun -n 2 (same numbers)
    python run_scripts/tools/make_figures.py gallery rotation

(``make figures`` runs the first line.) Each study is given ``--figures docs/figures``, so its
PNGs replace the documentation's, and writes its CSV into ``run_scripts/out/<study>/``; run on its own,
a study writes both into its ``--out`` folder and leaves ``docs/figures/`` alone. Runtime on a
2-core machine: ~25–35 minutes for the first seven, most of it the stability gallery's 3D bars
and the convergence study's 3D resolutions; ``fe_bar`` adds ~10 minutes, ``throughput`` and
``io_scaling`` ~3 each, ``energy_history`` and ``domains`` under one. The speed-accuracy,
throughput and scaling charts time the solver: run them on a quiet machine. ``scaling`` launches
``mpirun -n 1`` and ``-n 2`` itself, ``io_scaling`` ``mpirun -n 1, 2, 4, 8``, and
``throughput`` times one core, so ``--np`` does not apply to them.
"""
import argparse
import shutil
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parents[1]  # run_scripts/
FIGURES = HERE.parent / "docs" / "figures"
STUDIES = {
    "gallery": "studies/stability_gallery.py",
    "convergence": "studies/convergence.py",
    "update_order": "studies/update_order.py",
    "rotation": "studies/rotation.py",
    "fracture_alignment": "studies/fracture_alignment.py",
    "speed_accuracy": "studies/speed_accuracy.py",
    "scaling": "benchmarks/scaling.py",
    "fe_bar": "studies/fe_bar.py",
    "throughput": "benchmarks/throughput.py",
    "energy_history": "studies/energy_history.py",
    "domains": "tools/domains_picture.py",
    "io_scaling": "benchmarks/io_scaling.py",
}
#: studies that launch their own processes (bench runs): never wrapped in --np
LAUNCHERS = {"scaling", "throughput", "io_scaling"}
#: arguments a study's documentation figure is made with: the rotation page shows the disk
#: seeded on the grid's lattice, as measured there (docs/results/rotation.md compares the rings)
ARGS = {"rotation": ["--seeding", "lattice"]}


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("studies", nargs="*", help=f"which of {', '.join(STUDIES)} (default: all)")
    p.add_argument("--np", type=int, default=1, help="MPI ranks per study (default 1)")
    args = p.parse_args()
    names = args.studies or list(STUDIES)
    unknown = [n for n in names if n not in STUDIES]
    if unknown:
        p.error(f"unknown study {unknown[0]!r} (expected one of {', '.join(STUDIES)})")
    launcher = []
    if args.np > 1:
        mpirun = Path(sys.executable).parent / "mpirun"
        mpirun = str(mpirun) if mpirun.exists() else shutil.which("mpirun")
        if mpirun is None:
            print("make_figures: --np needs mpirun (install parmpm[mpich])", file=sys.stderr)
            return 2
        launcher = [mpirun, "-n", str(args.np)]
    for name in names:
        t0 = time.perf_counter()
        print(f"== {name}", flush=True)
        wrap = [] if name in LAUNCHERS else launcher
        proc = subprocess.run(wrap + [sys.executable, str(HERE / STUDIES[name]),
                                      "--figures", str(FIGURES), *ARGS.get(name, [])])
        if proc.returncode != 0:
            print(f"make_figures: {name} failed (exit {proc.returncode})", file=sys.stderr)
            return proc.returncode
        print(f"== {name}: {time.perf_counter() - t0:.0f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
