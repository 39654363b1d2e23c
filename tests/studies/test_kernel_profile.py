"""The kernel profiler (``run_scripts/tools/kernel_profile.py``) puts each sample on the
instruction that holds its address, and its shares add up: checked on hand-made samples and
``objdump`` text, and once for real (perf sampling a compiled kernel) where the machine allows."""
import os
import shutil
import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest
from tools import kernel_profile as K

ROOT = Path(__file__).resolve().parents[2]

OBJDUMP = """
/tmp/code.bin:     file format binary


Disassembly of section .data:

0000000000000000 <.data>:
   0:\t48 8b 44 24 30       \tmov    0x30(%rsp),%rax
   5:\tc5 f3 51 e9          \tvsqrtsd %xmm1,%xmm1,%xmm5
   9:\t48 8b 84 24 d8 00 00 \tmov    0xd8(%rsp),%rax
  10:\t00
  11:\tc3                   \tret
"""


def test_objdump_lines_become_offsets_and_instructions():
    code = K.parse_objdump(OBJDUMP)
    assert code == [(0x0, "mov    0x30(%rsp),%rax"), (0x5, "vsqrtsd %xmm1,%xmm1,%xmm5"),
                    (0x9, "mov    0xd8(%rsp),%rax"), (0x11, "ret")]


def test_samples_land_on_the_instruction_holding_their_address():
    base = 0x7F0000001000
    ips = Counter({base + 0x5: 7, base + 0x9: 3, base + 0xC: 2, base + 0x11: 1,
                   base - 4: 100, base + 0x10000: 50})
    hits = K.histogram(ips, base, 0x1000)
    assert hits == Counter({0x5: 7, 0x9: 3, 0xC: 2, 0x11: 1})  # outside the span: dropped
    code = K.parse_objdump(OBJDUMP)
    counts = K.by_instruction(hits, code)
    assert counts == [0, 7, 5, 1]  # 0xc lies inside the 8-byte mov at 0x9
    stretches = K.bins(code, counts, 2)
    assert [n for _, _, n in stretches] == [7, 6] and sum(counts) == 13
    text = K.report(code, counts, sum(ips.values()), 2, 3, context=1)
    assert "163 in all, 13 in the kernel (8.0 %)" in text  # 13 / 163
    blocks = text.split("hottest instructions")[1].split("  --- ")[1:]
    # hottest first (7, 5, 1 of 13 samples), each ending on its instruction
    assert [blk.splitlines()[0] for blk in blocks] == ["53.8 %", "38.5 %", "7.7 %"]
    assert [blk.splitlines()[-1].split()[-1] for blk in blocks] == ["%xmm1,%xmm1,%xmm5",
                                                                      "0xd8(%rsp),%rax", "ret"]


def test_code_is_read_from_this_process_up_to_an_unmapped_page():
    import ctypes
    buf = ctypes.create_string_buffer(b"\x90\xc3parmpm", 8)
    assert K.read_code(ctypes.addressof(buf), 8) == b"\x90\xc3parmpm"
    assert K.read_code(16, 64) == b""  # page zero is never mapped


def _perf_usable() -> bool:
    if shutil.which("perf") is None or shutil.which("objdump") is None:
        return False
    try:
        paranoid = int(Path("/proc/sys/kernel/perf_event_paranoid").read_text())
    except (OSError, ValueError):
        return False
    return paranoid <= 2


@pytest.mark.slow
@pytest.mark.skipif(not _perf_usable(), reason="needs perf (perf_event_paranoid <= 2), objdump")
def test_a_real_kernel_profile_puts_most_samples_in_the_kernel(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, str(ROOT / "run_scripts/tools/kernel_profile.py"),
                          "--method", "mpm", "--kernel", "g2p", "--particles", "2e5",
                          "--calls", "200", "--top", "3"], capture_output=True, text=True,
                         env=env, cwd=tmp_path, timeout=900)
    if "perf record failed" in out.stderr:
        pytest.skip(out.stderr.strip().splitlines()[-1])
    assert out.returncode == 0, out.stderr
    line = next(s for s in out.stdout.splitlines() if s.startswith("samples:"))
    share = float(line.split("(")[1].split(" %")[0])
    assert share > 50.0, out.stdout  # the calls are all the process does while sampled
    assert "ns per particle" in out.stdout and "hottest instructions" in out.stdout
