"""Where one compiled transfer kernel spends its time, instruction by instruction.

``parmpm bench`` times a step phase by phase; this looks inside one phase. It builds the bench
block (one rank), takes three steps with the chosen kernel of ``parmpm.step.transfers``' record
wrapped to catch its arguments, then calls that kernel alone ``--calls`` times under Linux
``perf record`` (sampling this process) and maps the samples onto the kernel's machine code,
read from this process's memory and disassembled with ``objdump``. numba writes no symbol map
for ``perf``, so the samples are placed by address: the kernel's entry point is its compiled
overload's, and the code read is the span from there to the last sampled instruction below
``--span`` bytes past it.

    python run_scripts/tools/kernel_profile.py --method mpm --kernel g2p --particles 1e6
    python run_scripts/tools/kernel_profile.py --method bspline --transfer mls --kernel p2g
    python run_scripts/tools/kernel_profile.py --method mpm --kernel g2p --dt 5e-5   # fixed step

It prints the kernel's share of the samples, the rate of the calls while sampled (perf costs a
few per cent), the share per ``--bins`` stretch of code, and the ``--top`` hottest instructions,
each with the instructions before it (a sample lands on the instruction after the one that
stalled, so a long-latency result shows on its first reader). Read it as where the retirement
waits, not as a cost per line: the out-of-order core overlaps independent work.

Needs ``perf`` (and permission to sample one's own process: ``kernel.perf_event_paranoid`` ≤ 2)
and ``objdump`` (binutils) on an x86-64 Linux machine; each is named in one line when missing.
"""
from __future__ import annotations

import argparse
import bisect
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

KERNELS = ("p2g", "g2p", "p2g_momentum")


def histogram(ips: Counter, base: int, span: int) -> Counter:
    """Samples per byte offset from ``base`` of the instruction pointers in ``[base, base+span)``."""
    return Counter({ip - base: n for ip, n in ips.items() if base <= ip < base + span})


def parse_objdump(text: str) -> list[tuple[int, str]]:
    """(offset, instruction text) of every line ``objdump -D`` prints for an instruction."""
    out = []
    for line in text.splitlines():
        head, sep, rest = line.partition(":\t")
        if not sep:
            continue
        try:
            offset = int(head.strip(), 16)
        except ValueError:
            continue
        parts = rest.split("\t")
        if len(parts) >= 2:  # bytes, then the mnemonic (a continuation line has bytes only)
            out.append((offset, parts[1].strip()))
    return out


def by_instruction(hits: Counter, code: list[tuple[int, str]]) -> list[int]:
    """Samples per instruction of ``code`` (sorted offsets); a sample between two starts (none
    should be) counts for the instruction it falls in."""
    starts = [o for o, _ in code]
    counts = [0] * len(code)
    for offset, n in hits.items():
        k = bisect.bisect_right(starts, offset) - 1
        if k >= 0:
            counts[k] += n
    return counts


def bins(code: list[tuple[int, str]], counts: list[int], nbins: int) -> list[tuple[int, int, int]]:
    """(first offset, last offset, samples) of ``nbins`` stretches of equal instruction count."""
    n = len(code)
    if n == 0:
        return []
    edges = [round(k * n / nbins) for k in range(nbins + 1)]
    return [(code[a][0], code[b - 1][0], sum(counts[a:b])) for a, b in zip(edges, edges[1:])
            if b > a]


def report(code: list[tuple[int, str]], counts: list[int], total: int, nbins: int, top: int,
           context: int = 3) -> str:
    """The text this tool prints about one kernel's samples."""
    inside = sum(counts)
    lines = [f"samples: {total} in all, {inside} in the kernel "
             f"({100.0 * inside / max(total, 1):.1f} %); {len(code)} instructions"]
    lines.append("by stretch of code (offsets in hex):")
    for a, b, n in bins(code, counts, nbins):
        lines.append(f"  {a:6x}-{b:6x} {n:7d} {100.0 * n / max(inside, 1):5.1f} %")
    lines.append(f"the {top} hottest instructions, each after the {context} before it:")
    order = sorted(range(len(code)), key=lambda k: -counts[k])[:top]
    for k in order:
        if counts[k] == 0:
            break
        lines.append(f"  --- {100.0 * counts[k] / max(inside, 1):.1f} %")
        for j in range(max(0, k - context), k + 1):
            lines.append(f"  {counts[j]:7d} {code[j][0]:6x}  {code[j][1]}")
    return "\n".join(lines)


def read_code(base: int, size: int) -> bytes:
    """Up to ``size`` bytes of this process's memory from ``base``, shorter where a page is not
    mapped (``/proc/self/mem`` refuses it)."""
    out = b""
    with open("/proc/self/mem", "rb", buffering=0) as mem:
        step = 4096 - base % 4096
        at = base
        while at < base + size:
            n = min(step, base + size - at)
            try:
                chunk = os.pread(mem.fileno(), n, at)
            except OSError:
                break
            out += chunk
            if len(chunk) < n:
                break
            at += n
            step = 4096
    return out


def disassemble(code: bytes) -> list[tuple[int, str]]:
    """``objdump``'s reading of raw x86-64 ``code`` (offset 0 at its first byte)."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "code.bin"
        path.write_bytes(code)
        text = subprocess.run(["objdump", "-D", "-b", "binary", "-m", "i386:x86-64", str(path)],
                              capture_output=True, text=True, check=True).stdout
    return parse_objdump(text)


def catch_kernel(args):
    """The bench block's stepper after three steps, the chosen kernel (a numba dispatcher) and
    the arguments of its last call."""
    import numpy as np
    from decomposition import world
    from parmpm.cli.bench import build_bench_scene
    from parmpm.driver.set_up import set_up

    scene = build_bench_scene(2, args.method, int(args.particles), update="usl", steps=10,
                              transfer=args.transfer, dt=args.dt)
    sim = set_up(scene, world())
    T = sim.stepper.transfers
    if T.kernels is None:
        raise SystemExit(f"kernel_profile: {args.method} runs on the generic loops in 2D; "
                         "expected an interpolator with specialised kernels")
    kernel = getattr(T.kernels, args.kernel)
    caught = {}

    def wrapper(*a):
        caught["args"] = a
        return kernel(*a)

    kernels = T.kernels
    T.kernels = kernels._replace(**{args.kernel: wrapper})
    try:
        for _ in range(3):
            sim.stepper.step(1e-5, np.zeros(3), 0.0)
    finally:
        T.kernels = kernels
    if "args" not in caught:
        raise SystemExit(f"kernel_profile: three steps of the bench block did not call "
                         f"{args.kernel} (an MLS step calls no p2g_momentum)")
    return kernel, caught["args"]


def entry_point(kernel, call_args) -> int:
    """The address of the overload of ``kernel`` that ``call_args`` select."""
    sig = tuple(kernel.typeof_pyval(a) for a in call_args)
    cres = kernel.overloads[sig]
    return cres.library.get_pointer_to_function(cres.fndesc.llvm_func_name)


def sample(kernel, call_args, calls: int, frequency: int) -> tuple[Counter, float]:
    """``perf`` samples (instruction pointer → count) of ``calls`` calls, and seconds per call."""
    with tempfile.TemporaryDirectory() as tmp:
        data = Path(tmp) / "perf.data"
        perf = subprocess.Popen(["perf", "record", "-F", str(frequency), "-p", str(os.getpid()),
                                 "-o", str(data)], stdout=subprocess.DEVNULL,
                                stderr=subprocess.PIPE, text=True)
        time.sleep(1.0)  # perf attaches
        if perf.poll() is not None:
            raise SystemExit(f"kernel_profile: perf record failed: {perf.stderr.read().strip()}")
        t0 = time.perf_counter()
        for _ in range(calls):
            kernel(*call_args)
        seconds = (time.perf_counter() - t0) / calls
        perf.send_signal(signal.SIGINT)
        perf.wait(timeout=120)
        text = subprocess.run(["perf", "script", "-i", str(data), "-F", "ip"], capture_output=True,
                              text=True, check=True).stdout
    ips = Counter(int(w, 16) for w in text.split())
    return ips, seconds


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--method", default="mpm", help="a 2D interpolator with specialised kernels")
    ap.add_argument("--transfer", default="flip", choices=("flip", "apic", "mls"))
    ap.add_argument("--kernel", default="g2p", choices=KERNELS)
    ap.add_argument("--dt", type=float, default=None,
                    help="a fixed step (time.dt, s): G2P's kernels without the wave speed")
    ap.add_argument("--particles", type=float, default=1e6)
    ap.add_argument("--calls", type=int, default=60)
    ap.add_argument("--frequency", type=int, default=10000, help="perf samples per second")
    ap.add_argument("--span", type=int, default=65536, help="bytes of code past the entry read")
    ap.add_argument("--bins", type=int, default=12)
    ap.add_argument("--top", type=int, default=12)
    args = ap.parse_args(argv)
    for tool in ("perf", "objdump"):
        if shutil.which(tool) is None:
            raise SystemExit(f"kernel_profile: {tool} not found on PATH (Linux perf and binutils "
                             "are needed)")
    kernel, call_args = catch_kernel(args)
    base = entry_point(kernel, call_args)
    ips, seconds = sample(kernel, call_args, args.calls, args.frequency)
    hits = histogram(ips, base, args.span)
    if not hits:
        raise SystemExit("kernel_profile: no sample fell in the kernel's code (too few calls?)")
    code = disassemble(read_code(base, max(hits) + 16))
    boxes = next(a for a in call_args if hasattr(a, "start") and hasattr(a, "nloc"))
    n = max(int(boxes.start[-1]), 1)
    print(f"{args.method} ({args.transfer}) {args.kernel}: {1e3 * seconds:.2f} ms per call, "
          f"{1e9 * seconds / n:.1f} ns per particle")
    print(report(code, by_instruction(hits, code), sum(ips.values()), args.bins, args.top))


if __name__ == "__main__":
    sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # the repository: parmpm
    main()
