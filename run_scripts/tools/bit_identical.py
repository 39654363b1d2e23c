"""Does a change leave every result bit for bit as it was? Save final states, then compare.

A renovation (a refactoring, a kernel regrouped, a formula moved) must not change one bit of any
result. This saves the final particle state (gid, x, v, F, stress, damage in global-id order) and
the summary's metrics, totals, step count and time of a fixed set of cases on 1-4 ranks, and
compares two such saves byte for byte. The cases (``rank_cases.py``) are the rank-independence
test's (``tests/mpi/test_mpi_ranks.py``: 1D/2D/3D, every interpolator, USL and MUSL, unscaled CPDI,
crossing and re-balancing, the manufactured solution, a spinning disk, damage and freezing, the
tension bar) plus linear elasticity and MUSL for every interpolator in 2D and 3D, 3D damage with
freezing, 3D unscaled CPDI and the vibrating bar (48 cases).

    python run_scripts/tools/bit_identical.py save BEFORE_DIR      # on the old code (a git worktree)
    python run_scripts/tools/bit_identical.py save AFTER_DIR       # on the new code
    python run_scripts/tools/bit_identical.py compare BEFORE_DIR AFTER_DIR

``save`` runs ``save_final_states.py`` under ``mpirun -n P`` for ``--ranks`` (default 1 2 3 4;
~4 minutes each on two cores). ``compare`` prints every field that differs and exits 1 if any
does, or if it found nothing to compare (it compares the rank counts present in the second
folder).
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run_scripts/: study.py, the groups
from tools.rank_cases import renovation_cases
from study import mpirun

ROOT = Path(__file__).resolve().parents[2]
FIELDS = ("gid", "x", "v", "F", "stress", "damage")
SUMMARY_KEYS = ("metrics", "final", "steps", "time")


def save(folder: Path, ranks: list[int]) -> None:
    spec = folder / "cases.json"
    folder.mkdir(parents=True, exist_ok=True)
    spec.write_text(json.dumps(renovation_cases()), encoding="utf-8")
    launcher = mpirun()
    if launcher is None:
        raise SystemExit("bit_identical: no mpirun found (install the mpich extra)")
    for n in ranks:
        out = folder / f"np{n}"
        out.mkdir(exist_ok=True)
        proc = subprocess.run([launcher, "-n", str(n), sys.executable,
                               str(ROOT / "run_scripts" / "tools" / "save_final_states.py"), str(out), str(spec)],
                              cwd=ROOT, capture_output=True, text=True, timeout=3600)
        if proc.returncode != 0:
            raise SystemExit(f"bit_identical: {n} ranks failed:\n{proc.stderr[-3000:]}")
        print(f"saved {len(list(out.glob('*.npz')))} cases on {n} rank(s) in {out}")


def compare(before: Path, after: Path) -> int:
    """Print every difference; the number of comparisons that differ."""
    bad = total = 0
    for folder in sorted(after.glob("np*")):
        for fb in sorted(folder.glob("*.npz")):
            fa = before / folder.name / fb.name
            if not fa.exists():
                print(f"missing in {before}: {fa.relative_to(before)}")
                bad += 1
                continue
            A, B = np.load(fa), np.load(fb)
            for k in FIELDS:
                total += 1
                a, b = A[k], B[k]
                if a.shape != b.shape or a.tobytes() != b.tobytes():
                    diff = np.max(np.abs(a - b)) if a.shape == b.shape else "shape"
                    print(f"differs: {folder.name}/{fb.stem} {k} (max |diff| {diff})")
                    bad += 1
            sa, sb = json.loads(str(A["summary"])), json.loads(str(B["summary"]))
            for k in SUMMARY_KEYS:
                total += 1
                if sa.get(k) != sb.get(k):
                    print(f"differs: {folder.name}/{fb.stem} summary {k}")
                    bad += 1
    print(f"{total} comparisons, {bad} differ")
    if total == 0:
        print(f"nothing to compare: no np*/ folder with cases in {after}")
        return 1
    return bad


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="command", required=True)
    s = sub.add_parser("save", help="run the cases and save their final states")
    s.add_argument("folder", type=Path)
    s.add_argument("--ranks", type=int, nargs="+", default=[1, 2, 3, 4])
    c = sub.add_parser("compare", help="compare two saves byte for byte")
    c.add_argument("before", type=Path)
    c.add_argument("after", type=Path)
    args = ap.parse_args()
    if args.command == "save":
        save(args.folder, args.ranks)
    else:
        sys.exit(1 if compare(args.before, args.after) else 0)


if __name__ == "__main__":
    main()
