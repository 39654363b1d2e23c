"""The broken-bar example (``docs/examples/broken_bar.toml``, 1D) as a square bar in 2D or 3D:
shared by the crack tests (``tests/step/test_crack.py``) and the crack-cost benchmark
(``run_scripts/benchmarks/crack_cost.py``)."""
from __future__ import annotations

import re
from pathlib import Path

BAR = Path(__file__).resolve().parents[2] / "docs" / "examples" / "broken_bar.toml"


def bar_text(text: str, dim: int) -> str:
    """The 1D example as a 0.04 m square bar in ``dim`` dimensions, four cells across (Poisson's
    ratio 0: the same uniaxial bar)."""
    if dim == 1:
        return text
    rest = dim - 1

    def vec(first: str, other: str) -> str:
        return "[" + ", ".join([first] + [other] * rest) + "]"

    grad = "[" + ", ".join(vec("1.0" if i == 0 else "0.0", "0.0") for i in range(dim)) + "]"
    out = []
    for line in text.splitlines():
        key, _, value = line.partition(" = ")
        if key == "dim":
            line = f"dim = {dim}"
        elif key == "origin":
            line = f"origin = {vec('-0.5', '-0.04')}"
        elif key == "cells":
            line = f"cells = {vec('100', '8')}"
        elif key in ("min", "max") and not value.startswith("["):
            line = f"{key} = {vec(value, '-0.02' if key == 'min' else '0.02')}"
        elif key in ("velocity", "value"):
            line = f"{key} = {vec(value, '0.0')}"
        elif key == "velocity_gradient":
            line = f"velocity_gradient = {grad}"
        elif key == "region":
            lo, hi = re.findall(r"-?[0-9.]+", value)
            line = f"region = {{ min = {vec(lo, '-1.0')}, max = {vec(hi, '1.0')} }}"
        out.append(line)
    return "\n".join(out) + "\n"
