"""What the study smoke tests share: run a ``run_scripts/`` study in ``--quick`` mode as a
subprocess (optionally under ``mpirun``), read its CSV, parse its numbers."""
from __future__ import annotations

import csv
import math
import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SCRIPTS = REPO / "run_scripts"


def run_quick(script: str, out: Path, prefix=(), extra=(), timeout=600) -> Path:
    """``python run_scripts/<script> --quick --out <out> <extra>`` (after ``prefix``, e.g.
    mpirun); fails the test with the script's output if it exits non-zero."""
    out.mkdir(parents=True, exist_ok=True)
    path = os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")]))
    env = dict(os.environ, PYTHONPATH=path)
    cmd = [*prefix, sys.executable, str(SCRIPTS / script), "--quick", "--out", str(out), *extra]
    proc = subprocess.run(cmd, cwd=out.parent, env=env, capture_output=True, text=True, timeout=timeout)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return out


def read_csv(path: Path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def num(value: str) -> float:
    """A CSV cell as a float (empty: NaN)."""
    return float(value) if value not in ("", None) else math.nan
