"""Published reference data kept in ``tests/data``: the files hold what their page says they hold.

``tests/data/bui2008_final_surface.csv`` is the digitised final surface and failure line of the
Bui et al. (2008) column collapse (copied, with its licence, from MaterialPointSolver.jl), and
``docs/results/plasticity_references.md`` quotes numbers read from it: the toe, the height at the
wall, the failure-line angle and the deposit's area. A future check of parmpm's collapse will
compare against this file, so a truncated copy or a page whose numbers drifted from the data
fails here, not in that check. ``tests/data/taylor_bar_references.csv`` holds the Taylor-bar radii
and lengths the same page recommends as targets (quoted from Carina.jl's benchmark).
"""
import csv
import math
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
BUI = ROOT / "tests" / "data" / "bui2008_final_surface.csv"
PAGE = ROOT / "docs" / "results" / "plasticity_references.md"


def bui_curves() -> dict[str, np.ndarray]:
    """The file's two curves, ``surface`` and ``failure``, as (n, 2) arrays of x, y in metres."""
    lines = [line for line in BUI.read_text(encoding="utf-8").splitlines()
             if not line.startswith("#")]
    rows = list(csv.DictReader(lines))
    return {name: np.array([[float(r["x"]), float(r["y"])] for r in rows if r["curve"] == name])
            for name in ("surface", "failure")}


def test_bui_file_names_its_source_and_licence():
    head = "".join(line for line in BUI.read_text(encoding="utf-8").splitlines(True)
                   if line.startswith("#"))
    for needle in ("LandslideSIM/MaterialPointSolver.jl", "doi:10.1002/nag.688",
                   "Copyright (c) 2022 Zenan Huo", "MIT License"):
        assert needle in head


def test_bui_curves_are_whole_and_inside_the_tank():
    c = bui_curves()
    assert len(c["surface"]) == 23 and len(c["failure"]) == 9
    for pts in c.values():
        assert np.all(np.diff(pts[:, 0]) > 0), "points run away from the wall"
        assert np.all(pts >= 0.0) and np.all(pts[:, 1] <= 0.1), "inside x >= 0, 0 <= y <= 0.1 m"


def test_bui_numbers_on_the_page_are_the_files():
    """Each number the page reads from the points, recomputed from the points."""
    s, f = bui_curves()["surface"], bui_curves()["failure"]
    page = PAGE.read_text(encoding="utf-8")
    toe = s[-1]
    ends = math.degrees(math.atan((f[0, 1] - f[-1, 1]) / (f[-1, 0] - f[0, 0])))
    slope, _ = np.polyfit(f[:, 0], f[:, 1], 1)
    area = float(np.sum(0.5 * (s[1:, 1] + s[:-1, 1]) * np.diff(s[:, 0])))
    quoted = {
        "x = 0.4423 m, y = 0.0015 m": (toe[0], 0.4423, toe[1], 0.0015),
        "| 0.0992 m (initial 0.1 m": (s[0, 1], 0.0992),
        "31.9° (end points)": (ends, 31.9),
        "32.9° (least-squares line)": (math.degrees(math.atan(-slope)), 32.9),
        "0.0203 m² against 0.0200 m²": (area, 0.0203),
    }
    for text, pairs in quoted.items():
        assert text in page, text
        for got, want in zip(pairs[::2], pairs[1::2]):
            assert round(got, 4 if want < 1 else 1) == want, (text, got)


TAYLOR = ROOT / "tests" / "data" / "taylor_bar_references.csv"


def taylor_rows() -> list[dict]:
    lines = [line for line in TAYLOR.read_text(encoding="utf-8").splitlines()
             if not line.startswith("#")]
    return list(csv.DictReader(lines))


def test_taylor_targets_on_the_page_are_the_files():
    """The recommended targets (R_f 7.22 mm, L_f 21.43 mm) and the published radii the page
    quotes are rows of the data file, and the file names its source and licence."""
    head = TAYLOR.read_text(encoding="utf-8")
    assert "Cthonios/Carina.jl" in head and "BSD-3-Clause" in head
    rows = taylor_rows()
    published = sorted(float(r["value_mm"]) for r in rows if r["kind"] == "published")
    assert published == [7.11, 7.12, 7.22]
    finest = {r["quantity"]: float(r["value_mm"]) for r in rows
              if r["kind"] == "fe_run" and r["h_mm"] == "0.19"}
    assert finest == {"radius": 7.2326, "length": 21.430}
    page = PAGE.read_text(encoding="utf-8")
    for text in ("R_f = 7.22 mm** (Foulk et al. 2021", "L_f = 21.43 mm**, the Sierra", "7.12 mm (Simo 1992)",
                 "7.11 mm (Zienkiewicz et al.", "| 7.2326 mm, 21.430 mm |"):
        assert text in page, text
    # the page's 2 % bands are 2 % of the targets, and the band contains every published radius
    assert "(7.08–7.36 mm)" in page and "21.00–21.86 mm" in page
    assert all(abs(r / 7.22 - 1) <= 0.02 for r in published)
    assert (round(7.22 * 0.98, 2), round(7.22 * 1.02, 2)) == (7.08, 7.36)
    assert (round(21.43 * 0.98, 2), round(21.43 * 1.02, 2)) == (21.0, 21.86)
