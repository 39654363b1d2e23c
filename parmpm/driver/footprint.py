"""Memory a scene will need, estimated before anything is allocated, and the check against what
the machine has.

A scene that cannot fit (``grid.ghost = 100000``, a huge ``ppc``, a CPDI ``l_cr`` of thousands of
cells) used to grow until the kernel killed it, exhausting a shared machine on the way. The
estimate counts what dominates, from the resolved scene alone:

* particles: counted per body from its lattice (a box exactly; a disk or sphere as the inscribed
  fraction π/4 or π/6 of its bounding lattice; a mesh from its elements, a particle file its rows,
  exactly: :func:`parmpm.scene.body_files.count`), times the bytes of every particle field
  (:data:`FIELD_BYTES`) times :data:`PEAK_FACTOR` (sorting, migration and seeding hold copies);
  with metrics, every rank also holds the whole scene's reference positions and masses;
* the separation check of the bar metrics: up to ``max(4^dim, (2·ghost + 2)^dim)`` node ids per
  particle, in three tables;
* the index arrays every rank keeps for every patch of the grid's bounding box (owner, count,
  slot, node box: :data:`DENSE_PATCH_BYTES`);
* patches: those within halo reach of a body's bounding box (an upper bound of what the run
  allocates), each ``(patch_size + 2·ghost + 1)^dim`` nodes of ``(1 + 4·dim)`` doubles, times
  :data:`PEAK_FACTOR` for the halo buffers;
* with ``[contact]``, every velocity field's grids on those patches and its share of the
  particle order (:func:`contact_bytes`; 100 default fields were estimated at 26 MiB and held
  1 GiB before they were counted).

Per rank that is ``(particles + patches + contact) / ranks`` plus the metrics' whole-scene share; the
ranks on one node together must fit in ``MemAvailable`` (``/proc/meminfo``), or in the bytes
``PARMPM_MEMORY_LIMIT`` gives (e.g. ``8G``; for batch jobs with a memory limit, and tests). Its
units are binary, as a batch system's (Slurm's ``--mem=8G``): K, M, G, T are KiB, MiB, GiB, TiB
(``8G``, ``8GB`` and ``8GiB`` all mean 8·2^30 bytes), and the messages say MiB and GiB too.
The interpreter and compiled kernels are already resident when the check runs, so they are
not counted.
"""
from __future__ import annotations

import math
import os

from parmpm.core.errors import ParmpmError
from parmpm.grid.update import row_stride
from parmpm.output.metrics import separation_kinds
from parmpm.scene.recorded_files import LISTED_SHAPES
from parmpm.scene.body_files import count
from parmpm.scene.contact import Contact
from parmpm.scene.records import Body, SceneSpec

#: measured peak over the bare fields (a 2D cpdi run at 1e6 particles: 360 B per particle over
#: 256 B of fields; the node blocks' halo buffers likewise)
PEAK_FACTOR = 1.5
#: bytes per patch of the whole (dense) patch grid that every rank keeps (measured 248 B with a
#: 2.5e3 x 4e3 patch grid): counts, owners, slots
#: and node boxes (decomposition.PatchLayout, PatchSet; parmpm.step.stepper.Discretisation)
DENSE_PATCH_BYTES = 256
#: the variable that overrides the memory available (bytes, or with a K, M, G or T suffix: binary
#: units, KiB to TiB)
LIMIT_VARIABLE = "PARMPM_MEMORY_LIMIT"
_UNITS = {"": 1, "K": 1 << 10, "M": 1 << 20, "G": 1 << 30, "T": 1 << 40}


def field_bytes(dim: int) -> int:
    """Bytes of one particle's fields (:class:`parmpm.particles.store.Particles`): ids, material and
    patch; x, v, x0, lh0, dx; mass, vol0, damage; F, stress, r0, rf."""
    return 8 * (3 + 5 * dim + 3 + 4 * dim * dim)


def _body_particles(body: Body, h: tuple[float, ...], dim: int) -> float:
    if body.shape in LISTED_SHAPES:  # listed: counted without making them
        return float(count(body, dim))
    ppc = body.ppc
    if body.shape == "box":
        return math.prod(max(1.0, round((hi - lo) / hk * p))
                         for lo, hi, hk, p in zip(body.min, body.max, h, ppc))
    if body.shape not in ("disk", "sphere"):  # polygon, cylinder, CSG, surface: its box's lattice
        lo, hi = body.bounds()
        return math.prod((b - a) / hk * p + 1 for a, b, hk, p in zip(lo, hi, h, ppc))
    inscribed = {1: 1.0, 2: math.pi / 4, 3: math.pi / 6}[dim]
    return inscribed * math.prod(2 * body.radius / hk * p + 1 for hk, p in zip(h, ppc))


def particles_estimate(spec: SceneSpec) -> float:
    """The scene's particles, counted from its bodies' keys without seeding them (listed bodies:
    their files' rows)."""
    return sum(_body_particles(b, spec.grid.cell_size, spec.dim) for b in spec.bodies)


def contact_bytes(contact: Contact | None, dim: int, particles: float, patches: float,
                  nodes: int) -> float:
    """What ``[contact]`` adds (:class:`parmpm.step.contact.ContactPhase`): per velocity field
    (body fields and crack far sides) and patch slot, its grid sums (1 + 2d rows), updated
    velocities (2d), first moments (1 + d), normal candidates (2d) and extents (4), and one
    mask row; with cracks the first three stacked in one row per field set, and the damage
    sums (2), maxima (1), gradient sums (d + d(d+1)/2) and crack normals (3); rows are
    :func:`~parmpm.grid.update.row_stride` doubles apart. Per particle: its field and its place
    in every field's order (8 bytes each), with cracks its damage gradient (3 doubles). Not
    times :data:`PEAK_FACTOR`: allocated once and never copied (measured: 1.03–1.2× the
    growth of the resident memory for 8 to 100 fields, 1.6× for 4)."""
    if contact is None:
        return 0.0
    d, K, stride = dim, contact.velocity_fields, row_stride(nodes)
    rows = K * (2 * d + 4) + 1  # normals, extents; the mask
    if contact.cracks:
        grid = (5 * d + 2) * row_stride(K * nodes) + (rows + 6 + d + d * (d + 1) // 2) * stride
    else:
        grid = (K * (5 * d + 2) + rows) * stride
    return 8 * (patches * grid + particles * (K + 1 + (3 if contact.cracks else 0)))


def estimate(spec: SceneSpec, ghost: int, ranks: int = 1) -> dict:
    """The estimate for a scene (``scene.spec``, its ``grid.patch_size`` chosen) with ``ghost``
    ghost cells on ``ranks`` ranks: particles, patches, nodes per patch and the peak bytes per
    rank."""
    d, grid = spec.dim, spec.grid
    h, origin, cells = grid.cell_size, grid.origin, grid.cells
    psize = grid.patch_size
    particles = particles_estimate(spec)
    patches = 0.0
    for body in spec.bodies:
        lo, hi = body.bounds()
        count = 1.0
        for k in range(d):
            a = max(0, math.floor((lo[k] - origin[k]) / h[k]) - ghost - 1)
            b = min(cells[k] - 1, math.floor((hi[k] - origin[k]) / h[k]) + ghost + 1)
            count *= max(0, b // psize[k] - a // psize[k] + 1)
        patches += count
    dense = math.prod(math.ceil(n / p) for n, p in zip(cells, psize))
    patches = min(patches, dense)
    nodes = math.prod(p + 2 * ghost + 1 for p in psize)
    per_rank = (PEAK_FACTOR * (particles * field_bytes(d) + patches * nodes * 8 * (1 + 4 * d))
                + contact_bytes(spec.contact, d, particles, patches, nodes)) / ranks
    per_rank += DENSE_PATCH_BYTES * dense  # every rank indexes every patch of the bounding grid
    kind = spec.metrics.kind
    if kind != "none":  # whole-scene x0, mass and patch of every particle
        per_rank += particles * 8 * (d + 2)
    if kind in separation_kinds():  # the separation check's node table: K node ids per particle
        K = max(4 ** d, (2 * ghost + 2) ** d)
        per_rank += 3 * 8 * K * particles / ranks
    return {"particles": particles, "patches": patches, "dense_patches": dense, "nodes_per_patch": nodes,
            "bytes_per_rank": per_rank}


def available_bytes() -> float | None:
    """Memory this node can still give: ``PARMPM_MEMORY_LIMIT`` if set, else MemAvailable (None
    when neither is known)."""
    text = os.environ.get(LIMIT_VARIABLE, "").strip().upper().removesuffix("B").removesuffix("I")
    if text:
        unit = text[-1] if text[-1] in _UNITS and not text[-1].isdigit() else ""
        try:
            value = float(text[:-1] if unit else text) * _UNITS[unit]
        except ValueError:
            value = -1.0
        if not (math.isfinite(value) and value > 0):
            raise ParmpmError(f"{LIMIT_VARIABLE}={os.environ[LIMIT_VARIABLE]!r}: expected a "
                              "number of bytes, optionally with K, M, G or T (binary: KiB, MiB, "
                              "GiB, TiB; e.g. 8G)")
        return value
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024
    except OSError:
        pass
    return None


def _gb(n: float) -> str:
    """Bytes in the binary units ``PARMPM_MEMORY_LIMIT`` is read in (8G shows as 8 GiB)."""
    for unit in ("T", "G", "M"):
        if n >= _UNITS[unit]:
            return f"{n / _UNITS[unit]:.3g} {unit}iB"
    return f"{n / _UNITS['K']:.3g} KiB"


def check_memory(spec: SceneSpec, ghost: int, ranks: int = 1, ranks_here: int = 1,
                 available: float | None = None) -> dict:
    """Raise a one-line ParmpmError when the ``ranks_here`` ranks of this node need more than
    ``available`` bytes (default: :func:`available_bytes`); returns the estimate."""
    est = estimate(spec, ghost, ranks)
    available = available_bytes() if available is None else available
    need = est["bytes_per_rank"] * ranks_here
    if available is not None and need > available:
        fields = (f"{spec.contact.velocity_fields} contact velocity fields, " if spec.contact
                  else "")
        raise ParmpmError(
            f"scene '{spec.name}' needs about {_gb(est['bytes_per_rank'])} per rank "
            f"({est['particles']:.3g} particles, {est['patches']:.3g} patches of "
            f"{est['nodes_per_patch']:.3g} nodes of {est['dense_patches']:.3g} in the grid, "
            f"ghost {ghost} cells, {fields}{ranks} rank(s)), "
            f"{_gb(need)} for the {ranks_here} rank(s) on this node, which has {_gb(available)} "
            f"available; use fewer particles or cells, a smaller ghost width or l_cr, or more "
            f"nodes ({LIMIT_VARIABLE} overrides the limit)")
    return est
