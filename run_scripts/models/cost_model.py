"""A per-step cost model of the patch-parallel MPM step, fitted to ``scaling.py``'s measurements.

Pure numpy (no MPI, no parmpm): every function below is a formula, tested by hand-computed cases
in ``tests/studies/test_scaling.py``. ``run_scripts/benchmarks/scaling.py`` measures the constants, checks the model
against the runs it made and writes the predictions (``cost_model.csv``, ``cost_model.json``,
``cost_model.png``).

**Time per step on P ranks** (the slowest rank sets the pace)::

    T(P) = (N/P)·t_p·(1 + ι)                    compute: particles per rank × time per particle-step
         + n_msg·α                              latency: one message per neighbour rank and exchange
         + (B_halo + B_mig)/β                   bandwidth: bytes this rank sends per step
         + α_r·⌈log2 P⌉                         the end-of-step Allreduce (recursive doubling)

    E(P) = T(1) / (P·T(P)),   T(1) = N·t_p       (strong-scaling efficiency)

* ``t_p`` — seconds per particle-step on one rank with no communication: the 1-rank bench's
  time per step minus its halo (accumulate, fill) and reduce phases, over the particle count
  (:func:`compute_time_per_particle`). It includes the grid update and the local patch-to-patch
  particle moves. Intra-rank halo copies (≈ 1 % of a 1-rank step) are left out of the model.
* ``ι`` — load imbalance, max/mean − 1 of particles per rank. Measured runs: the bench's value.
  Predictions: given by the caller (``scaling.py`` splits the cube's patches along the Morton
  curve with ``decomposition.assign``, as a run would), else ``ι = 0.5/m`` for ``m`` patches per
  rank (whole patches are the unit of distribution: on average half a patch above the mean).
* **Halo bytes.** Patch A and its neighbour B = A + o (offset ``o ∈ {-1,0,1}^d``) exchange, per
  halo operation and per field component, ``n(o) + n(−o)`` nodes, where ``n(o) = Π_a e(o_a)`` is
  the part of A's owned box held as ghosts by B: ``e(0) = s_a`` (A's owned nodes along a),
  ``e(+1) = g`` and ``e(−1) = g + 1`` (patch ``k`` owns nodes ``[k·s, (k+1)·s)`` and holds
  ``[k·s − g, (k+1)·s + g]``; :func:`pair_halo_nodes`). For a shared **face** (one non-zero
  offset) that is ``(2g + 1)·s^(d−1)`` nodes. Accumulate sends ``c_a = 1 + 2d`` doubles per node
  (mass, momentum, force), fill ``c_f = 2d`` (velocity, velocity increment) under USL
  (MUSL: ``1 + 3d`` and ``3d``), so one face costs ``8·(c_a + c_f)·(2g + 1)·s^(d−1)`` bytes per
  step, both directions together (:func:`face_halo_bytes`).
* A rank holding a cube of ``k^d`` patches, surrounded by other ranks, sends per halo operation
  and component ``H(k) = Σ_{m=1..d} C(d,m)·[k^d − k^(d−m)·(k−1)^m]·(2g+1)^m·s^(d−m)`` nodes
  (the pairs with an offset of ``m`` non-zero axes that leave the cube, summed over the 2^m
  sign patterns; ``H(1) = (s + 2g + 1)^d − s^d``, a single patch's ghost nodes), so
  ``B_halo = 8·(c_a + c_f)·H(k)`` (:func:`rank_halo_nodes`).
* ``n_msg = n_ops·min(3^d − 1, P − 1)``: each halo operation (accumulate, fill) and the
  migration send one message to every neighbour rank, empty or not (``n_ops`` = 3 under USL,
  5 under MUSL).
* **Migration**: particles leave the cube of side ``L = k·s`` cells at ``ppc^d·L^(d−1)·u`` per
  step for a drift of ``u`` cells per step (summed over axes), each a row of
  ``w = 6 + 5d + 3d²`` doubles (:func:`particle_row_doubles`), ``B_mig = 8·w·ppc^d·L^(d−1)·u``.
  Its latency is in ``n_msg``. Measured runs are not used to fit it: there the migrate phase is
  mostly waiting for the slower rank.
* ``α`` (s) and ``β`` (bytes/s) — the Hockney fit ``t(n) = α + n/β`` of one-way ping-pong
  times over 8 B … 4 MiB (:func:`fit_latency_bandwidth`); ``α_r`` (s per stage) — the time of an
  Allreduce of 5 doubles over ``⌈log2 P⌉`` (:func:`fit_reduction`).

**Predictions for a cluster** (:func:`predict_cube`): a 3D cube of N particles, ``ppc`` particles
per cell per axis (``n = N^(1/3)/ppc`` cells per axis), cubic patches of ``s`` cells,
``n_p = (n/s)^3`` patches, ``m = n_p/P`` per rank (``k = m^(1/3)``); ``P > n_p`` is infeasible
(a rank would hold less than a patch). The network is *assumed* (not measured here):
``α = α_sw + α_net``, where ``α_sw`` is the measured same-node latency (the mpi4py/MPICH software
cost of a message) and ``α_net`` the wire latency; ``β = min(β_measured, β_net)``;
``α_r = α_r,measured + α_net`` per stage. Every neighbour rank is taken to be off-node and every
rank's sub-domain a cube of patches (Morton pieces are less compact: more halo).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from itertools import product

import numpy as np

#: bench phases that are communication (subtracted from a 1-rank step to get t_p); any other
#: phase (including ones added later) counts as compute; "halo" is the bench's own sum of two.
COMM_PHASES = ("accumulate", "fill", "reduce")
AGGREGATE_PHASES = ("halo",)


@dataclass(frozen=True)
class Machine:
    """Communication constants: latency α (s), bandwidth β (bytes/s), Allreduce stage α_r (s)."""

    alpha: float
    beta: float
    alpha_r: float

    def as_dict(self) -> dict:
        return asdict(self)


# --- geometry ----------------------------------------------------------------------------------
def halo_components(dim: int, update: str = "usl") -> tuple[int, int]:
    """Doubles per node (accumulate, fill): USL ``(1 + 2d, 2d)`` — mass, momentum, force; velocity,
    velocity increment. MUSL adds a second momentum accumulate and velocity fill: ``(1 + 3d, 3d)``."""
    return (1 + 2 * dim, 2 * dim) if update == "usl" else (1 + 3 * dim, 3 * dim)


def halo_ops(update: str = "usl") -> int:
    """Messages per neighbour rank and step: accumulate + fill (+ a second pair in MUSL) + migrate."""
    return 3 if update == "usl" else 5


def directed_halo_nodes(offset, extent, ghost: int):
    """``n(o) = Π_a e(o_a)``: nodes of patch A's owned box that the patch at ``A + offset`` holds as
    ghosts; ``e(0) = extent_a`` (A's owned nodes along a), ``e(+1) = g``, ``e(−1) = g + 1``
    (each capped at ``extent_a``). ``extent``: a scalar, a (d,) vector or an (n, d) array (one
    patch per row, then one count per row)."""
    o = np.atleast_1d(np.asarray(offset, dtype=np.int64))
    e = np.asarray(extent, dtype=np.int64)
    e = np.broadcast_to(e, o.shape) if e.ndim == 0 else e
    cap = np.where(o > 0, ghost, ghost + 1)
    n = np.prod(np.where(o == 0, e, np.minimum(e, cap)), axis=-1)
    return int(n) if np.ndim(n) == 0 else n


def pair_halo_nodes(offset, extent, ghost: int):
    """Nodes exchanged per halo operation and component between a patch and its neighbour at
    ``offset``, both directions: ``n(o) + n(−o)`` (same owned ``extent`` on both sides along the
    zero-offset axes, as for any two patches in one row)."""
    o = np.atleast_1d(np.asarray(offset, dtype=np.int64))
    return directed_halo_nodes(o, extent, ghost) + directed_halo_nodes(-o, extent, ghost)


def face_halo_bytes(s: int, ghost: int, dim: int, update: str = "usl") -> int:
    """Bytes per step across one shared patch face (both directions, accumulate + fill):
    ``8·(c_a + c_f)·(2g + 1)·s^(d−1)``."""
    c_a, c_f = halo_components(dim, update)
    return 8 * (c_a + c_f) * (2 * ghost + 1) * s ** (dim - 1)


def rank_halo_nodes(k: float, s: int, ghost: int, dim: int) -> float:
    """``H(k)``: nodes an interior rank holding a cube of ``k^d`` patches sends per halo operation
    and component, ``Σ_m C(d,m)·[k^d − k^(d−m)(k−1)^m]·(2g+1)^m·s^(d−m)`` (``k ≥ 1``, real)."""
    if k < 1:
        raise ValueError(f"a rank must hold at least one patch (k = {k})")
    return float(sum(math.comb(dim, m) * (k ** dim - k ** (dim - m) * (k - 1) ** m)
                     * (2 * ghost + 1) ** m * s ** (dim - m) for m in range(1, dim + 1)))


def neighbour_offsets(dim: int) -> list[tuple[int, ...]]:
    """The ``3^d − 1`` offsets of the adjacent patches (or ranks)."""
    return [o for o in product((-1, 0, 1), repeat=dim) if any(o)]


def particle_row_doubles(dim: int) -> int:
    """Doubles per migrating particle: gid, mat, patch; x, v, x0, lh0, dx (d each); mass, vol0,
    damage; F, stress, r0 (d² each): ``6 + 5d + 3d²``."""
    return 6 + 5 * dim + 3 * dim * dim


def neighbour_ranks(P: int, dim: int) -> int:
    """Neighbour ranks of an interior rank: ``min(3^d − 1, P − 1)``."""
    return min(3 ** dim - 1, max(P - 1, 0))


# --- fits --------------------------------------------------------------------------------------
def compute_time_per_particle(result: dict) -> float:
    """``t_p`` (s) from a 1-rank bench result: ``(seconds_per_step − Σ comm phases) / particles``.
    Communication phases are :data:`COMM_PHASES`; every other phase, whatever its name, is work."""
    phases = result["phase_seconds_per_step"]
    comm = sum(float(v) for k, v in phases.items() if k in COMM_PHASES)
    return (float(result["seconds_per_step"]) - comm) / float(result["particles"])


def fit_latency_bandwidth(nbytes, seconds) -> tuple[float, float]:
    """Hockney fit ``t(n) = α + n/β`` of one-way message times; returns (α s, β bytes/s).

    Least squares in *relative* error, ``Σ_i ((α + n_i·b − t_i)/t_i)²`` with ``b = 1/β``, so that
    8-byte and 4-MiB messages weigh alike (plain least squares would fit the large sizes only and
    leave α to chance). α is clamped to ≥ 0 and b to > 0.
    """
    n = np.asarray(nbytes, dtype=np.float64)
    t = np.asarray(seconds, dtype=np.float64)
    if n.size < 2 or np.any(t <= 0):
        raise ValueError("need at least two positive times")
    A = np.stack([1.0 / t, n / t], axis=1)
    (alpha, b), *_ = np.linalg.lstsq(A, np.ones_like(t), rcond=None)
    if b <= 0:  # no size dependence resolved: bandwidth from the largest message
        b = float(t[np.argmax(n)] / n.max())
    if alpha < 0:  # latency below resolution: refit b alone through the origin
        alpha = 0.0
        b = float(np.sum(n / t) / np.sum((n / t) ** 2))
    return float(alpha), float(1.0 / b)


def fit_reduction(ranks, seconds) -> float:
    """``α_r`` (s per stage): least squares through the origin of Allreduce times against
    ``⌈log2 P⌉`` (ranks ≤ 1 carry no information and are skipped)."""
    P = np.asarray(ranks, dtype=np.float64)
    t = np.asarray(seconds, dtype=np.float64)
    stages = np.ceil(np.log2(np.maximum(P, 1.0)))
    keep = stages > 0
    if not np.any(keep):
        raise ValueError("need an Allreduce time on 2 or more ranks")
    x, y = stages[keep], t[keep]
    return float(np.dot(x, y) / np.dot(x, x))


# --- the model ---------------------------------------------------------------------------------
def step_time(N: float, P: int, t_p: float, machine: Machine, *, halo_bytes: float = 0.0,
              n_msg: float = 0.0, imbalance: float = 0.0, migration_bytes: float = 0.0) -> dict:
    """The terms of ``T(P)`` (seconds per step) and their total; shares of the total."""
    terms = {
        "compute": N / P * t_p * (1.0 + imbalance),
        "latency": n_msg * machine.alpha,
        "bandwidth": (halo_bytes + migration_bytes) / machine.beta,
        "reduce": machine.alpha_r * math.ceil(math.log2(P)) if P > 1 else 0.0,
    }
    total = sum(terms.values())
    out = dict(terms, total=total)
    out.update({f"{k}_share": v / total if total > 0 else 0.0 for k, v in terms.items()})
    return out


def efficiency(T1: float, P: int, TP: float) -> float:
    """Strong-scaling efficiency ``E = T1 / (P·T_P)``."""
    return T1 / (P * TP)


def cube_geometry(N: float, P: int, ppc: int, s: int, dim: int = 3) -> dict:
    """Cells per axis ``n = N^(1/d)/ppc``, patches ``n_p = (n/s)^d``, per rank ``m = n_p/P``,
    ``k = m^(1/d)`` (patches per rank per axis), feasible when ``m ≥ 1``."""
    n = N ** (1.0 / dim) / ppc
    n_p = (n / s) ** dim
    m = n_p / P
    return {"cells_per_axis": n, "patches": n_p, "patches_per_rank": m,
            "k": m ** (1.0 / dim), "feasible": m >= 1.0}


def predict_cube(N: float, P: int, t_p: float, machine: Machine, *, dim: int = 3, ppc: int = 2,
                 s: int = 16, ghost: int = 2, update: str = "usl", drift: float = 0.01,
                 imbalance: float | None = None) -> dict:
    """``T(P)``, ``E(P)`` and the shares for a cube of ``N`` particles on ``P`` ranks (see the
    module docstring); ``E`` and ``T`` are NaN where ``P`` exceeds the patch count. ``imbalance``
    (max/mean − 1 of particles per rank) defaults to ``0.5/m``."""
    geo = cube_geometry(N, P, ppc, s, dim)
    row = {"particles": float(N), "ranks": int(P), **geo}
    nan_terms = {k: math.nan for k in ("compute", "latency", "bandwidth", "reduce", "total",
                                       "compute_share", "latency_share", "bandwidth_share",
                                       "reduce_share")}
    if not geo["feasible"]:
        return dict(row, **nan_terms, imbalance=math.nan, halo_bytes=math.nan,
                    migration_bytes=math.nan, messages=math.nan, efficiency=math.nan)
    if P == 1:
        halo = mig = msgs = imb = 0.0
    else:
        k = geo["k"]
        c_a, c_f = halo_components(dim, update)
        halo = 8.0 * (c_a + c_f) * rank_halo_nodes(k, s, ghost, dim)
        mig = 8.0 * particle_row_doubles(dim) * ppc ** dim * (k * s) ** (dim - 1) * drift
        msgs = float(halo_ops(update) * neighbour_ranks(P, dim))
        imb = 0.5 / geo["patches_per_rank"] if imbalance is None else float(imbalance)
    T = step_time(N, P, t_p, machine, halo_bytes=halo, n_msg=msgs, imbalance=imb,
                  migration_bytes=mig)
    return dict(row, **T, imbalance=imb, halo_bytes=halo, migration_bytes=mig, messages=msgs,
                efficiency=efficiency(N * t_p, P, T["total"]))


def network_machine(measured: Machine, alpha_net: float, beta_net: float) -> Machine:
    """Constants for ranks on different nodes: ``α = α_sw + α_net``, ``β = min(β, β_net)``,
    ``α_r = α_r + α_net`` (the measured same-node values are the software cost of a message)."""
    return Machine(alpha=measured.alpha + alpha_net, beta=min(measured.beta, beta_net),
                   alpha_r=measured.alpha_r + alpha_net)
