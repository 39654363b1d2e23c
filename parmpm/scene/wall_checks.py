"""Walls against the scene (issue 41): a wall whose plane cuts a body, a body wholly behind its
wall, and a wall whose plane misses the grid are each one warning line, said once, by rank 0,
before the first step.

Why warnings and not errors: each scene runs as written, and each can be meant (a wall that
starts inside a body to cut it free, a grid drawn round one part of a long slope); but each is
more often a mistake — a normal pointing into the wall instead of out of it, a point off by a
sign — whose run says nothing: a body behind a wall is stopped wherever its nodes approach the
plane, and a wall outside the grid never touches a node.

A particle is behind a wall when its reference centre is, ``(x₀ − p)·n < 0`` (a body resting on
the wall has its centres half a spacing in front). Each rank counts its own particles per wall
and body (a body's particles are a range of global ids) and the counts are summed over the
ranks, so the lines are the same on any number of ranks. The grid test needs no particles: the
plane misses the grid when every corner of the grid's box is on one side of it, at the start
and, for a moving wall, at the end of the run (``p(t) = p₀ + v ∫₀ᵗ f``; a wall that passes
through the grid and back out between is not flagged, nor a moving wall in a run given as a
number of steps, whose end is not known at set-up).
"""
from __future__ import annotations

import itertools

import numpy as np

from decomposition import is_parallel
from parmpm.core.log import get_logger

log = get_logger(__name__)


def _vec(v) -> str:
    return "[" + ", ".join(f"{x:.4g}" for x in v) + "]"


def behind_counts(spec, first: np.ndarray, gid: np.ndarray, x0: np.ndarray) -> np.ndarray:
    """(walls, bodies, 2): of these particles (global ids ``gid``, increasing; body ``j``'s are
    ``first[j] ≤ gid < first[j + 1]``), how many start behind each wall and how many in all."""
    out = np.zeros((len(spec.walls), len(spec.bodies), 2), np.int64)
    for j in range(len(spec.bodies)):
        a, b = np.searchsorted(gid, [first[j], first[j + 1]])
        for w, wall in enumerate(spec.walls):
            s = (x0[a:b] - np.asarray(wall.point)) @ np.asarray(wall.normal)
            out[w, j] = int(np.count_nonzero(s < 0.0)), b - a
    return out


def grid_side(spec, wall) -> str | None:
    """"in front of" or "behind" where the grid's box lies wholly on that side of the wall's
    plane at the start and (a moving wall) at the end; None where the plane crosses it."""
    g = spec.grid
    lo = np.asarray(g.origin, float)
    hi = lo + np.asarray(g.cells) * np.asarray(g.cell_size)
    corners = np.array(list(itertools.product(*zip(lo, hi))))
    times = [0.0]
    if wall.moves:
        if spec.time.end is None:  # a run of so many steps: its end is not known yet
            return None
        times.append(spec.time.end)
    sides = set()
    for t in times:
        point = np.asarray(wall.point) + np.asarray(wall.velocity) * wall.time.integral(t)
        s = (corners - point) @ np.asarray(wall.normal)
        sides.add("in front of" if np.all(s > 0.0) else "behind" if np.all(s < 0.0) else None)
    return sides.pop() if len(sides) == 1 else None


def messages(spec, counts: np.ndarray) -> list[str]:
    """The warnings' lines from the summed :func:`behind_counts`."""
    lines = []
    for w, wall in enumerate(spec.walls):
        plane = f"point {_vec(wall.point)}, normal {_vec(wall.normal)}"
        side = grid_side(spec, wall)
        if side is not None:
            lines.append(f"walls.{w} ({plane}) misses the grid: the whole grid lies {side} its "
                         "plane" + (", so it can touch nothing" if side == "in front of" else
                                    ", so every body is behind it") + " (move its point into "
                         "the grid, or leave the wall out)")
            if side == "in front of":
                continue
        for j in range(len(spec.bodies)):
            behind, n = (int(v) for v in counts[w, j])
            if n and behind == n:
                lines.append(f"bodies.{j} lies wholly behind walls.{w} ({plane}; the normal "
                             f"points out of the wall, towards the bodies): the wall holds it "
                             "wherever it moves against the normal (flip the normal?)")
            elif behind:
                lines.append(f"walls.{w} ({plane}) cuts bodies.{j}: {behind} of its {n} "
                             "particles start behind the plane, where the wall holds them (move "
                             "the wall to the body's surface)")
    return lines


def check_walls(comm, spec, seeds, gid: np.ndarray, x0: np.ndarray) -> list[str]:
    """The walls' warnings, logged once, by rank 0 (collective: every rank passes its own
    particles, global ids ``gid`` at reference positions ``x0``; ``seeds``: the
    :class:`parmpm.particles.seeding.Seeds` they came from). Returns the lines (the same on
    every rank)."""
    if not spec.walls:
        return []
    first = np.concatenate([[0], np.cumsum([len(c[0]) for c in seeds.chunks])]).astype(np.int64)
    gid, x0 = np.asarray(gid, np.int64), np.asarray(x0, float).reshape(-1, spec.dim)
    if np.any(np.diff(gid) < 0):
        order = np.argsort(gid, kind="stable")
        gid, x0 = gid[order], x0[order]
    counts = behind_counts(spec, first, gid, x0)
    if is_parallel(comm):
        counts = np.sum(comm.allgather(counts), axis=0)
    lines = messages(spec, counts)
    if comm is None or comm.Get_rank() == 0:
        for line in lines:
            log.warning("%s", line)
    return lines
