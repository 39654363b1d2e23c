"""What each ``parmpm`` command does once the command line is parsed and MPI is up (the error
policy around them is :mod:`parmpm.cli.main`'s). The solver is imported inside each command, so
``parmpm scenes`` and ``parmpm show`` stay fast."""
from __future__ import annotations

import argparse
import os
import sys


def cmd_scenes() -> int:
    from parmpm.scene.load import builtin_scenes

    scenes = builtin_scenes()
    width = max((len(name) for name in scenes), default=0)
    try:
        for name, description in scenes.items():
            print(f"{name:<{width}}  {description}".rstrip(), flush=True)
    except BrokenPipeError:  # `parmpm scenes | head -1`: the reader left; say nothing more
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    return 0


def cmd_show(args: argparse.Namespace) -> int:
    """The resolved scene as TOML on stdout: ``parmpm run`` of it runs the same scene."""
    from parmpm.scene.load import load_scene

    text = load_scene(args.scene, overrides=args.overrides).to_toml()
    try:
        sys.stdout.write(text)
        sys.stdout.flush()
    except BrokenPipeError:  # `parmpm show | head`: the reader left; say nothing more
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    return 0


def cmd_run(args: argparse.Namespace, rank: int, comm) -> int:
    from parmpm.scene.agreement import load_shared_scene

    # read once by rank 0, shared, compared on every rank (parmpm.scene.agreement); before the
    # heavy imports below
    scene = load_shared_scene(comm, args.scene, overrides=args.overrides)

    from parmpm.driver.simulation import Simulation
    from parmpm.driver.warm_up import compile_first, compile_notice
    from parmpm.io.summary import format_summary

    with compile_notice():
        summary = Simulation(scene, args.out, quiet=args.quiet or rank != 0, comm=comm,
                             overwrite=args.overwrite, warm_up=compile_first).run()
    if rank == 0:
        print(format_summary(summary), flush=True)
    return 0


def cmd_restart(args: argparse.Namespace, rank: int, comm) -> int:
    from parmpm.driver.simulation import Simulation
    from parmpm.driver.warm_up import compile_first, compile_notice
    from parmpm.io.summary import format_summary

    with compile_notice():
        sim = Simulation.from_checkpoint(args.checkpoint, args.overrides, args.out,
                                         quiet=args.quiet or rank != 0, comm=comm,
                                         overwrite=args.overwrite, warm_up=compile_first)
        summary = sim.run()
    if rank == 0:
        print(format_summary(summary), flush=True)
    return 0


def cmd_bench(args: argparse.Namespace, rank: int, comm) -> int:
    from parmpm.cli.bench import run_benches
    from parmpm.driver.warm_up import compile_notice

    with compile_notice():
        run_benches(args, comm)  # rank 0 prints the tables
    return 0


def cmd_compile(args: argparse.Namespace, rank: int, comm) -> int:
    from parmpm.cli.compile import run_compile

    return run_compile(args, comm)
