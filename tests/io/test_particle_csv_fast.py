"""The fast read of a CSV particle table (issue 41): the row-by-row reader's particles and
errors, bit for bit and word for word, on tables plain and damaged in every way the reader
names; no Python string per row; rows repeating an earlier row's position noted."""
import csv
from decimal import Decimal, getcontext

import numpy as np
import pytest
from test_particle_file import _arrays, _same, _write_csv

from parmpm.core.errors import SceneError
from parmpm.io.particle_file import read_particle_file

NUMBERS = ["1_0", "+.5", "-0", "-0.0", "1.", "00012", "4.9e-324", "2.2250738585072014e-308",
           "1.7976931348623157e308", "9007199254740993", "1" + "0" * 25, "0.1e-5", "7E+2",
           "12345678901234567890123", "0.30000000000000004", "5e-324", "1e-400", "-1.5e+300"]


def _outcome(label, run):
    """The ParticleData's arrays as bytes (so -0.0 differs from 0.0), or the error's text."""
    try:
        p = run()
    except SceneError as exc:
        return str(exc)
    return [None if a is None else (a.dtype.str, a.shape, a.tobytes())
            for a in (p.x, p.volume, p.velocity, p.material, p.F)] + [p.repeats]


def _table(rng, comma=True, crlf=False, bom=False, gaps=False, material=True, n=40):
    """A 2D table of ``n`` rows with numbers of every form ``float()`` takes (``NUMBERS``, reprs
    of random doubles, short %g), as text; the laid-out rows kept for damaging them."""
    head = ["x", "Y", "volume", "vx", "vy"] + (["material"] if material else [])

    def pick():
        if rng.random() < 0.3:
            return NUMBERS[rng.integers(len(NUMBERS))]
        if rng.random() < 0.7:
            return repr(float(rng.standard_normal() * 10.0 ** rng.integers(-8, 8)))
        return f"{rng.standard_normal():.3g}"

    rows = []
    for _ in range(n):
        volume = repr(float(rng.uniform(0.1, 2.0))) if rng.random() < 0.8 else "2.5e-3"
        row = [pick(), pick(), volume, pick(), pick()] + ([["rock", "ice"][rng.integers(2)]]
                                                          if material else [])
        rows.append(row)
    return head, rows, dict(comma=comma, crlf=crlf, bom=bom, gaps=gaps)


def _text(head, rows, comma, crlf, bom, gaps, rng):
    sep = ", " if comma else " \t "
    lines = ["# particles", sep.join(head)]
    for row in rows:
        if gaps and rng.random() < 0.2:
            lines.append(["", "   ", "# a comment, 1, 2", "  #x"][rng.integers(4)])
        lines.append(("  " if rng.random() < 0.2 else "") + sep.join(row))
    text = ("\r\n" if crlf else "\n").join(lines) + ("\n" if rng.random() < 0.7 else "")
    return ("\ufeff" if bom else "") + text


DAMAGE = ["abc", "", "nan", "inf", "1e999", "-1", "0", "drop", "extra", "é", '"1.5"', "1e", "0x1p3"]


@pytest.mark.parametrize("seed", range(40))
def test_csv_fast_read_is_the_precise_read(tmp_path, seed):
    """Any table, plain or damaged: the fast read gives the row-by-row reader's particles bit
    for bit (-0.0, subnormals, 1_0, 25 digits) or its error word for word; it leaves to that
    reader only non-ASCII text and quotes."""
    from parmpm.io.particle_file import fast_table, table

    rng = np.random.default_rng(seed)
    head, rows, lay = _table(rng, comma=seed % 2 == 0, crlf=seed % 3 == 0, bom=seed % 5 == 0,
                             gaps=seed % 4 < 2, material=seed % 7 != 0)
    damage = DAMAGE[seed % len(DAMAGE)] if seed >= 8 else None
    if damage is not None:
        r, c = int(rng.integers(len(rows))), int(rng.integers(3))
        if damage == "drop":
            del rows[r][c]
        elif damage == "extra":
            rows[r].append("1")
        elif damage == "é" and len(head) == 6:
            rows[r][5] = "granité"
        else:
            rows[r][2 if damage in ("-1", "0") else c] = damage
    path = tmp_path / "t.csv"
    path.write_bytes(_text(head, rows, rng=rng, **lay).encode())
    raw = path.read_bytes()
    fast = _outcome("", lambda: read_particle_file(path, 2))
    label = f"particle file '{path}'"
    assert fast == _outcome("", lambda: table.read_precise(label, raw, 2)), fast
    if damage in (None, "abc", "", "nan", "drop", "-1"):  # the fast read itself, no hand-over
        try:
            assert fast_table.read_fast(label, path, raw, 2) is not None
        except SceneError:
            assert isinstance(fast, str)


def test_csv_rows_are_no_python_strings(tmp_path, monkeypatch):
    """A 3000-row table is split without the csv module or str.split per row (the cause of
    133 s and 5.1 GB for 10⁷ rows): the header alone goes through them."""
    a = _arrays(3000, 3, seed=4)
    _write_csv(tmp_path / "big.csv", a, 3)
    calls = []
    reader = csv.reader
    monkeypatch.setattr(csv, "reader", lambda *args, **kw: calls.append(1) or reader(*args, **kw))
    _same(read_particle_file(tmp_path / "big.csv", 3), a)
    assert len(calls) <= 1, len(calls)


def test_repeated_rows_are_noted(tmp_path):
    """Rows at an earlier row's position (-0.0 = 0.0): counted with the volume they add and
    the first pair's lines; distinct positions (equal in one coordinate only) note nothing."""
    (tmp_path / "twice.csv").write_text("x, y, volume\n# every row twice\n0, 1, 0.5\n2, 3, 0.25\n"
                                        "0, 1, 0.5\n\n-0.0, 3, 1\n2, 3, 0.25\n0.0, 3, 2\n")
    p = read_particle_file(tmp_path / "twice.csv", 2)
    assert p.repeats == (f"particle file '{tmp_path / 'twice.csv'}': 3 row(s) repeat an "
                         "earlier row's position (the first: line 5 repeats line 3); they add "
                         "volume 2.75, 61.1 % of the file's total 4.5 (each is one more particle, "
                         "its mass counted again); remove them unless meant")
    (tmp_path / "apart.csv").write_text("x, y, volume\n0, 1, 1\n0, 2, 1\n1, 1, 1\n")
    assert read_particle_file(tmp_path / "apart.csv", 2).repeats == ""
    np.savez(tmp_path / "twice.npz", x=np.zeros((3, 1)), volume=np.ones(3))
    assert "2 row(s) repeat an earlier row's position (the first: row 1 repeats row 0)" in (
        read_particle_file(tmp_path / "twice.npz", 1).repeats)


def test_csv_fast_numbers_are_float_of_their_text(tmp_path):
    """30 000 numbers of every kind the compiled conversion meets (random doubles' reprs,
    subnormals and the largest, %.1g to %.19g, 19-digit mantissas at exponents -340 .. 308,
    decimals half-way between two doubles, 2^53 + k, exact expansions of 50+ digits and the
    midpoints between doubles) read by the fast pass as ``float()`` reads each text, bit for
    bit."""
    from parmpm.io.particle_file import fast_table

    getcontext().prec = 900
    rng = np.random.default_rng(41)
    bits = rng.integers(0, 2**64, 6000, dtype=np.uint64, endpoint=False)
    d = bits.view(np.float64)
    texts = [repr(float(v)) for v in d[np.isfinite(d)]]
    v = rng.standard_normal(6000) * 10.0 ** rng.integers(-300, 300, 6000)
    texts += [f"{x:.{k % 19 + 1}g}" for k, x in enumerate(v.tolist())]
    m = rng.integers(10**18, 10**19, 6000, dtype=np.uint64)
    texts += [f"{a}e{b}" for a, b in zip(m.tolist(), rng.integers(-340, 290, 6000).tolist())]
    lo = rng.uniform(1.0, 2.0, 6000)  # the decimal midpoint of lo and the next double
    texts += [repr(float(a)) + "000005" if k % 2 else f"{a:.17e}" for k, a in enumerate(lo.tolist())]
    texts += [str(2**53 + k) for k in range(-50, 50)]
    for a in v[:500].tolist():  # > 19 digits: exact expansions, midpoints and either side
        mid = (Decimal(a) + Decimal(float(np.nextafter(a, np.inf)))) / 2
        texts += [f"{Decimal(a):e}", f"{mid:e}", f"{mid * (1 + Decimal(10) ** -40):e}"]
    texts += ["-" + t for t in texts[6000:8000] if not t.startswith("-")]
    path = tmp_path / "n.csv"
    path.write_text("x volume\n" + "".join(f"{t} 1\n" for t in texts))
    label = f"particle file '{path}'"
    assert fast_table.read_fast(label, path, path.read_bytes(), 1) is not None
    got = read_particle_file(path, 1).x[:, 0]
    want = np.array([float(t) for t in texts])
    assert np.array_equal(got.view(np.uint64), want.view(np.uint64))
