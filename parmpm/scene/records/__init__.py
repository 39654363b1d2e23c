"""The resolved scene as typed, frozen records: what every layer below the schema reads.

:func:`parmpm.scene.schema.resolve` checks a scene and returns it as a nested dict, the
*serialised form* (``Scene.data``: written as ``scene.toml``, hashed across ranks, stored in
checkpoints, changed by restart keys). :meth:`SceneSpec.from_resolved` turns that dict into
these records, in one place and by one rule, so that a misspelt name is an ``AttributeError``
(a lint in ``tests/scene/test_scene_records.py``), not a ``KeyError`` deep in a run:

* every table becomes the record its field is annotated with; an array of tables a tuple of
  records; ``materials`` a read-only mapping (:class:`FrozenMap`) of name → :class:`Material`;
* every list becomes a tuple (``grid.cells``, ``bodies.0.velocity_gradient``): nothing in a
  record can change after it is made;
* a key the dict holds and no field names is a ``TypeError`` (a schema key without a record
  field), a field the dict lacks takes its default (``None``: a disk has no ``min``, a scene
  without APIC's transfer has ``method.flip``, without damage ``damage``).

The modules below :mod:`parmpm.scene` (output, particles, transfer, ...) may not import this one
(the layers, :data:`parmpm.LAYERS`): they take these records as arguments and read their fields.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from parmpm.geometry import csg
from parmpm.geometry.primitives import body_bounds, inside
from parmpm.scene import body_files
from parmpm.scene.check import lcr_length
from parmpm.scene.contact import Contact
from parmpm.scene.loads import Load, Wall
from parmpm.scene.records.build import FrozenMap, build

#: the interpolators that cap their domains at ``method.lcr`` (:mod:`parmpm.scene.schema`)
LCR_INTERPOLATORS = ("cpdi", "cpdi2")
#: the bodies :mod:`parmpm.geometry.primitives` places (seeded as before CSG came)
PRIMITIVE_SHAPES = ("box", "disk", "sphere")
#: the bodies read from a file (:mod:`parmpm.scene.body_files`)
FILE_SHAPES = ("mesh", "surface", "particles")

Floats = tuple[float, ...]
Ints = tuple[int, ...]


@dataclass(frozen=True, slots=True)
class Grid:
    """``[grid]``: per-axis tuples of length ``dim``; ``"auto"`` where set-up chooses."""

    origin: Floats
    cell_size: Floats
    cells: Ints
    patch_size: Ints | str       # "auto": chosen from the scene (parmpm.scene.patch_size)
    ghost: int | str             # "auto": the interpolator's reach
    exterior: int | str          # "auto": the ghost width on faces a body starts near

    @property
    def dim(self) -> int:
        return len(self.cells)

    @property
    def min_dx(self) -> float:
        """Smallest grid spacing, min_k Δx_k."""
        return min(self.cell_size)


@dataclass(frozen=True, slots=True)
class Damage:
    """``[materials.NAME.damage]`` (:mod:`parmpm.materials.damage`)."""

    criterion: str
    onset: float
    fracture: float
    softening: str
    freeze: float | str          # "never": a CPDI domain never freezes


@dataclass(frozen=True, slots=True)
class Material:
    """``[materials.NAME]``: the elastic keys, and a plastic model's flat keys
    (:mod:`parmpm.scene.materials`), None where the model does not use them."""

    model: str
    density: float
    youngs_modulus: float
    poisson_ratio: float
    damage: Damage | None = None
    yield_stress: float | None = None            # j2: sigma_y0 (Johnson-Cook's A)
    hardening: str | None = None                 # j2: "linear" | "swift" | "johnson_cook"
    hardening_modulus: float | None = None       # linear H, Johnson-Cook B
    hardening_exponent: float | None = None      # Swift, Johnson-Cook n
    strength_coefficient: float | None = None    # Swift A
    rate_coefficient: float | None = None        # Johnson-Cook C
    reference_rate: float | None = None          # Johnson-Cook rate0 (1/s)
    friction_angle: float | None = None          # drucker_prager: degrees
    dilatancy_angle: float | None = None
    cohesion: float | None = None
    matching: str | None = None                  # "plane_strain" | "outer" | "inner"
    tension_cutoff: float | None = None          # None: the apex
    volume_correction: bool | None = None        # drucker_prager: dilation given back free
    friction_angle_2: float | None = None        # drucker_prager, mu(I): None is off
    inertial_number_0: float | None = None       # mu(I)'s I_0
    grain_diameter: float | None = None          # mu(I)'s d (m)
    grain_density: float | None = None           # mu(I)'s rho_s (None: the material's density)


@dataclass(frozen=True, slots=True)
class Vibration:
    """``[bodies.vibration]``: a box's initial vibration mode along ``axis``."""

    amplitude: float
    mode: int
    axis: int


@dataclass(frozen=True, slots=True)
class Part:
    """One of a CSG body's ``parts`` (:mod:`parmpm.geometry.csg`): a primitive (its fields as
    on :class:`Body`, plus a half-space's ``point`` and outward ``normal``) or a combination of
    ``parts``; the fields of the other shapes are None."""

    shape: str
    min: Floats | None = None
    max: Floats | None = None
    angle: float | None = None
    center: Floats | None = None
    radius: float | None = None
    axis: str | None = None
    length: float | None = None
    vertices: tuple[Floats, ...] | None = None
    point: Floats | None = None
    normal: Floats | None = None
    parts: tuple[Part, ...] | None = None

    def bounds(self, dim: int) -> tuple[list, list]:
        """Axis-aligned bounds, ``±inf`` where unbounded (:func:`parmpm.geometry.csg.bounds`)."""
        return csg.bounds(self, dim)

    def inside(self, dim: int, x):
        """Which points ``x`` (n, dim) lie strictly inside (:func:`parmpm.geometry.csg.inside`)."""
        return csg.inside(self, dim, x)


@dataclass(frozen=True, slots=True)
class Body:
    """One ``[[bodies]]`` table: a box (``min``, ``max``, ``angle``), a disk / sphere
    (``center``, ``radius``), a cylinder (``axis``, ``center``, ``radius``, ``length``), a
    polygon (``vertices``), a CSG combination (``parts``, :class:`Part`) or a body read from a
    ``file`` (a mesh's ``groups`` and ``split``, a particle file's ``step``:
    :mod:`parmpm.scene.body_files`); the fields of the other shapes are None. A mesh or particle
    body has no ``ppc`` (None), a particle body whose file names materials no ``material``."""

    shape: str
    material: str | None
    ppc: Ints | None
    velocity: Floats
    angle: float | None
    angular_velocity: float | Floats | None    # 2D: a number, 3D: a vector
    velocity_gradient: tuple[Floats, ...] | None
    vibration: Vibration | None
    min: Floats | None = None
    max: Floats | None = None
    center: Floats | None = None
    radius: float | None = None
    axis: str | None = None
    length: float | None = None
    vertices: tuple[Floats, ...] | None = None
    parts: tuple[Part, ...] | None = None
    file: str | None = None
    groups: tuple[str | int, ...] | None = None
    split: int | None = None
    step: int | None = None
    file_size: int | None = None     # what the run read: parmpm.scene.recorded_files
    file_sha256: str | None = None
    seeding: str | None = None   # "conforming" | "lattice"; None: listed (mesh, particles)

    @property
    def dim(self) -> int:
        return len(self.velocity)

    def bounds(self) -> tuple[list, list]:
        """Axis-aligned bounds: a box's corners (a turned box's bounding box), a disk's or
        sphere's centre ± radius (:func:`parmpm.geometry.primitives.body_bounds`), a file body's
        (:func:`parmpm.scene.body_files.bounds`), another shape's
        :func:`parmpm.geometry.csg.bounds` (finite: the schema checks it)."""
        if self.shape in PRIMITIVE_SHAPES:
            return body_bounds(self)
        if self.shape in FILE_SHAPES:
            return body_files.bounds(self, self.dim)
        return csg.bounds(self, self.dim)

    def inside(self, dim: int, x):
        """Which points ``x`` (n, dim) lie strictly inside (:func:`parmpm.geometry.primitives.inside`,
        :func:`parmpm.geometry.csg.inside`, :func:`parmpm.scene.body_files.inside`)."""
        if self.shape in PRIMITIVE_SHAPES:
            return inside(self, dim, x)
        if self.shape in FILE_SHAPES:
            return body_files.inside(self, dim, x)
        return csg.inside(self, dim, x)

    def listed(self, dim: int):
        """A mesh's or particle file's points (:class:`parmpm.scene.body_files.Listed`)."""
        return body_files.listed(self, dim)

    def count(self) -> int:
        """How many particles a mesh or particle body makes (:func:`parmpm.scene.body_files.count`)."""
        return body_files.count(self, self.dim)


@dataclass(frozen=True, slots=True)
class Method:
    """``[method]``; ``flip`` is None under APIC and MLS (no blend)."""

    interpolator: str
    lcr: float | str             # metres, "<k>dx", "<k>dx/<n>" or "none"
    update: str                  # "auto", "usl" or "musl"
    transfer: str
    flip: float | None = None


@dataclass(frozen=True, slots=True)
class Gravity:
    g: Floats
    ramp_time: float


@dataclass(frozen=True, slots=True)
class Damping:
    coefficient: float


@dataclass(frozen=True, slots=True)
class Manufactured:
    """``[manufactured]``: the manufactured solution's amplitude (:mod:`parmpm.loads.manufactured`)."""

    amplitude: float


@dataclass(frozen=True, slots=True)
class Box:
    """An axis-aligned box ``{min, max}``: a fixed region, a probe's region."""

    min: Floats
    max: Floats


@dataclass(frozen=True, slots=True)
class SlipRegion:
    """A box whose nodes have zero velocity along ``normal`` ("x", "y" or "z")."""

    min: Floats
    max: Floats
    normal: str


@dataclass(frozen=True, slots=True)
class Boundary:
    """``[boundary]``: the face conditions of the scene's axes (None beyond ``dim``) and the
    regions inside the grid."""

    fixed_regions: tuple[Box, ...]
    slip_regions: tuple[SlipRegion, ...]
    regions_with_splines: bool | None = None   # held regions kept under B-splines (a study)
    x_min: str | None = None
    x_max: str | None = None
    y_min: str | None = None
    y_max: str | None = None
    z_min: str | None = None
    z_max: str | None = None

    @property
    def faces(self) -> tuple[tuple[str, str], ...]:
        """``(min, max)`` condition per axis of the scene."""
        pairs = ((self.x_min, self.x_max), (self.y_min, self.y_max), (self.z_min, self.z_max))
        return tuple(p for p in pairs if p[0] is not None)


@dataclass(frozen=True, slots=True)
class Time:
    end: float | None
    steps: int | None
    cfl: float
    dt_max: float | None
    max_energy_growth: float | str   # "off": no blow-up watch
    dt: float | None = None          # a fixed step instead of the CFL one


@dataclass(frozen=True, slots=True)
class Probe:
    """One ``[[output.history.probes]]``: exactly one of ``point``, ``region``, ``body``,
    ``material`` is set."""

    name: str
    point: Floats | None
    region: Box | None
    body: int | None
    material: str | None
    fields: tuple[str, ...]
    stats: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class History:
    """``[output.history]`` (:mod:`parmpm.scene.history`)."""

    enabled: bool
    every: float | None
    every_steps: int | None
    probes: tuple[Probe, ...]


@dataclass(frozen=True, slots=True)
class Output:
    every: float | None
    every_steps: int | None
    snapshots: bool
    figure: bool
    domains: bool
    history: History


@dataclass(frozen=True, slots=True)
class Metrics:
    kind: str
    every_steps: int
    axis: int
    stop_on_separation: bool
    grip: str | None


@dataclass(frozen=True, slots=True)
class Decomposition:
    rebalance_threshold: float
    rebalance_cooldown: int


@dataclass(frozen=True, slots=True)
class Checkpoint:
    every_steps: int | None
    every: float | None
    wall_minutes: float | None
    keep: int
    at_end: bool
    ranks_per_file: int | str      # "auto": one part file per rank up to 256 ranks


@dataclass(frozen=True, slots=True)
class SceneSpec:
    """The whole resolved scene (``scene.spec``); build it with :meth:`from_resolved`."""

    name: str
    description: str
    dim: int
    grid: Grid
    materials: Mapping[str, Material]
    bodies: tuple[Body, ...]
    method: Method
    gravity: Gravity
    damping: Damping
    boundary: Boundary
    manufactured: Manufactured | None
    time: Time
    output: Output
    metrics: Metrics
    decomposition: Decomposition
    checkpoint: Checkpoint
    walls: tuple[Wall, ...] = ()
    loads: tuple[Load, ...] = ()
    contact: Contact | None = None

    @classmethod
    def from_resolved(cls, data: dict) -> SceneSpec:
        """The records of a resolved scene (:func:`parmpm.scene.schema.resolve`'s dict)."""
        return build(cls, data)

    @property
    def min_dx(self) -> float:
        return self.grid.min_dx

    @property
    def lcr(self) -> float | None:
        """CPDI domain-scaling length l_cr in metres; None unless cpdi or cpdi2 with scaling."""
        if self.method.interpolator not in LCR_INTERPOLATORS:
            return None
        return lcr_length(self.method.lcr, self.min_dx)


__all__ = ["SceneSpec", "Grid", "Material", "Damage", "Body", "Part", "Vibration", "Method", "Gravity",
           "Damping", "Manufactured", "Box", "SlipRegion", "Boundary", "Time", "Probe", "History",
           "Output", "Metrics", "Decomposition", "Checkpoint", "Wall", "Load", "Contact", "FrozenMap",
           "build"]
