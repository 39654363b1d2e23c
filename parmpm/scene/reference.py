"""The scene reference: every key a scene may hold, in its resolved form. ``docs/gen`` builds the
manual's key pages from this text and the schema's key tuples, and fails the strict build when
the schema accepts a key this text never names.

Scene reference (resolved form; "(default X)" marks optional keys; per-axis quantities take a
scalar, broadcast to every axis, or a list of ``dim`` values; points and vectors (``min``,
``max``, ``center``, ``velocity``, ``g``) take a list of ``dim`` numbers, or a scalar in 1D):

* top level: ``name`` (default: file stem / built-in name; 1 to 100 letters, digits, spaces,
  ``_ - . +``, starting with a letter or digit: it names the output files), ``description``
  (default ""), ``dim`` (1, 2 or 3; required), the arrays of tables ``walls`` and ``loads``
  (below; absent from the resolved scene when empty), the table ``contact`` (below; absent
  when not given). A scene file is a regular file of at most 1 MiB,
  UTF-8 (a byte order mark is allowed); an integer has at most 4300 digits (Python's limit).
* ``[grid]``: ``origin`` (default 0), ``cell_size`` (> 0, required), ``cells`` (ints > 0,
  required), ``patch_size`` ("auto" or ints > 0, default "auto": chosen from the scene
  alone, :mod:`parmpm.scene.patch_size`; clipped to ``cells``),
  ``ghost`` ("auto" or int from 1 to the largest cell count, default "auto"); every node
  coordinate must resolve a cell (``|origin|`` and the extent below 1e12 cells), ``exterior`` ("auto" or int 0..64, default
  "auto": cells kept outside the faces, the face conditions staying on the faces; "auto" gives the
  ghost width on each face a body starts within one cell of, :func:`parmpm.transfer.discretisation.exterior_cells`).
* ``[materials.NAME]`` (at least one): ``model`` ("linear_elastic" | "neo_hookean") or a
  plastic model ("j2" | "drucker_prager", below), ``density`` (> 0), ``youngs_modulus``
  (> 0), ``poisson_ratio`` (-1 < nu < 0.5); all required, and together they must give a
  positive, finite wave speed (no subnormal moduli).
  Optional ``[materials.NAME.damage]``: ``onset`` (stretch >= 1, required), ``fracture``
  (> onset, required), ``softening`` ("linear" | "exponential", default linear), ``criterion``
  ("max_principal_stretch", the only one), ``freeze`` (0 < D <= 1 or "never", default 1: the damage at which a CPDI
  domain freezes, :mod:`parmpm.shapes.freeze`).
  The plastic models (:mod:`parmpm.materials.plasticity`, docs/concepts/plasticity.md) take the
  same three elastic keys (the Hencky moduli K = E/(3(1 − 2ν)), G = E/(2(1 + ν))), no
  ``damage``, and flat keys of their own; a key of another model or another hardening law is an
  error. ``model = "j2"`` (finite-strain von Mises): ``yield_stress`` (> 0 Pa, required: the
  initial yield stress σ_y0), ``hardening`` ("linear" | "swift" | "johnson_cook", default
  "linear"), ``hardening_modulus`` (>= 0 Pa, default 0; linear: σ_y = σ_y0 + H ε̄p, 0 perfectly
  plastic; Johnson–Cook's B), ``strength_coefficient`` (> 0 Pa; "swift" only, required: σ_y =
  A (ε0 + ε̄p)^n with ε0 = (σ_y0/A)^(1/n), which must be finite and > 0),
  ``hardening_exponent`` (0 < n <= 1; required with "swift" and "johnson_cook"),
  ``rate_coefficient`` (>= 0, default 0: no rate term; "johnson_cook" only, its C),
  ``reference_rate`` (> 0 1/s, default 1; "johnson_cook" only): Johnson–Cook's σ_y =
  (σ_y0 + B ε̄p^n)(1 + C ln max(ε̄̇p/reference_rate, 1)). ``model = "drucker_prager"``:
  ``friction_angle`` (degrees, 0 <= φ < 90, required), ``dilatancy_angle`` (degrees,
  0 <= ψ <= φ, default 0: no dilatancy), ``cohesion`` (>= 0 Pa, default 0; φ = 0 needs c > 0),
  ``matching`` ("plane_strain" | "outer" | "inner", default "plane_strain": which Mohr–Coulomb
  limit the cone reproduces), ``tension_cutoff`` (Pa, from 0 to the apex ξ c / η; default
  absent: the apex), ``volume_correction`` (true | false, default false: true gives the volume
  a particle gained plastically — at the cut-off, or by dilatancy — back free of stress under
  compression, so loose grains press only once denser than they started; Tampubolon et al.
  2017, docs/concepts/drucker-prager.md); the μ(I) rheology (GDR MiDi 2004; Jop, Forterre &
  Pouliquen 2006), for cohesionless grains (c = 0): ``friction_angle_2`` (degrees, φ < φ_2 < 90;
  given, it turns μ(I) on: the cone's slope rises from φ's to φ_2's, under the same matching, as
  η(I) = η_s + (η_2 − η_s) I/(I_0 + I) with the inertial number I = γ̇_p d / √(P/ρ_s)),
  ``inertial_number_0`` (> 0, required with it: I_0), ``grain_diameter`` (> 0 m, required with
  it: d), ``grain_density`` (> 0, default the material's density: ρ_s); checked by
  :func:`parmpm.materials.plasticity.drucker_prager.drucker_prager_constants`.
* ``[[bodies]]`` (at least one): ``shape`` ("box", "disk" in 2D, "sphere" in 3D; default "box");
  box: ``min``, ``max``; disk/sphere: ``center``, ``radius``; ``material`` (required);
  ``ppc`` (particles per cell per axis, 1 to 1000, default 2; a disk or sphere must hold at
  least one point of its lattice); ``seeding`` ("conforming" | "lattice"; default "conforming"
  for a round body — a disk, sphere or cylinder, or a CSG body that is one of them (alone in a
  one-part combination), an annulus (a disk minus smaller concentric disks) or a tube (a
  cylinder minus thinner coaxial cylinders as long or longer) —, "lattice" elsewhere, where
  "conforming" is an error; not for bodies from files): "conforming" cuts a disk or annulus
  into rings (a sphere into shells, each in bands and sectors; a cylinder or tube into its
  cross-section's rings extruded in layers along its axis) about a particle spacing wide (the
  spacing ``Δx/ppc``, the geometric mean over the axes), one particle per cell at its centroid
  with the cell's exact area or volume and a CPDI domain along its radius, so the outer (and
  inner) particles follow the surface and the masses add up to ``ρ π (R² − r_in²)``
  (``ρ (4/3) π R³``, ``ρ π (R² − r_in²) L``) (:mod:`parmpm.particles.seeding.conforming`);
  "lattice" keeps the points of the grid-aligned lattice inside the shape (a disk then has flats
  where the circle meets a lattice row); ``velocity`` (default 0); optional
  ``[bodies.vibration]`` (box only): ``amplitude`` (required), ``mode`` (default 1), ``axis``
  (default 0): initial velocity along ``axis`` is ``amplitude·sin(β_n (X − min[axis]))`` with
  ``β_n = (2n − 1)π / (2L)``, ``L`` the box length along ``axis`` (the first mode of a bar fixed
  at ``min[axis]`` and free at ``max[axis]``; Sulsky et al. 1995, Bardenhagen 2002);
  ``angular_velocity`` (2D: a number, rad/s counter-clockwise; 3D: a vector; default none): adds
  the rigid spin ``ω × (x − centre)`` about the body's centre; ``velocity_gradient`` (a
  ``dim``×``dim`` list of rows, 1/s; default none): adds the affine field ``L·(x − centre)`` (a
  bar stretched at a rate from the start); ``angle`` (box only, 2D/3D, degrees counter-clockwise
  about the box centre in the x-y plane; default none): turns the box, its particle lattice and
  its CPDI domains (GIMP domains stay axis-aligned). Every body's (turned) bounding box lies
  inside the grid. More shapes (:mod:`parmpm.scene.parts`, :mod:`parmpm.geometry.csg`):
  "polygon" (2D): ``vertices`` (3 to 1000 points ``[x, y]``, a simple polygon, either
  orientation); "cylinder" (3D): ``axis`` ("x" | "y" | "z"), ``center`` (its mid-point),
  ``radius``, ``length`` (along the axis); "union" | "intersection" | "difference" (the first
  part minus the others): ``parts``, a list of 1 to 100 inline tables, each a shape with its own
  keys (box, disk, sphere, cylinder, polygon, a nested combination up to 8 deep, or "half_space":
  ``point`` and outward ``normal``, only as a part that cuts a bounded one). Seeded on a disk's
  lattice kept by the inside test (a round one conforming, above); spin and velocity gradient about the bounding box's centre.
  Bodies from files (:mod:`parmpm.scene.body_files`, docs/concepts/geometry_files.md): "mesh"
  (2D/3D; one particle per quadrature point, no ``ppc``): ``file`` (a volume mesh meshio reads;
  a relative path is relative to the scene file's folder, resolved to an absolute one),
  ``groups`` (optional list of Gmsh physical groups or cell sets, names or ids), ``split``
  (1 to 16, default 1: each element cut into split^dim before the rule); "surface" (3D):
  ``file`` (STL, OBJ or PLY), seeded as a CSG body on the lattice the winding number keeps;
  "particles": ``file`` (.csv, .npz, .h5 or a parmpm snapshot or checkpoint), ``step``
  (optional: which step of a snapshot series), no ``ppc``; ``material`` may be left out when
  the file names each particle's material. Every file body's resolved form records what the run
  read: ``file_size`` (bytes) and ``file_sha256`` (64 lower-case hex digits); given in a scene
  (a recorded ``scene.toml`` run again) a file whose digest differs is read as it is now, with a
  warning; a restart whose file is gone or changed continues from its checkpoint's records
  (:mod:`parmpm.scene.recorded_files`).
* ``[method]``: ``interpolator`` ("mpm" | "ugimp" | "cpgimp" | "cpdi" | "bspline" | "cpdi2",
  default "cpdi"), ``lcr``
  (CPDI domain-scaling length: metres, "<k>dx", "<k>dx/<n>" or "none", at most the largest
  cell count or 64 cells, whichever is more; default "2dx" for cpdi and cpdi2,
  "none" otherwise, and any other value is an error with another interpolator), ``update``
  ("auto" | "usl" | "musl", default "auto": USL for cpdi and cpdi2, whose domains then keep tiling the body exactly, MUSL for the others, which USL destabilises through nearly empty nodes — docs/concepts/update-orders.md), ``flip`` (0..1, default 1.0;
  not with APIC or MLS), ``transfer`` ("flip" | "apic" | "mls", default "flip"; "apic" and
  "mls" need "bspline": :mod:`parmpm.transfer.affine`).
* ``[gravity]``: ``g`` (default 0), ``ramp_time`` (>= 0 s, default 0: applied suddenly).
* ``[damping]``: ``coefficient`` (>= 0 1/s, default 0).
* ``[boundary]``: ``x_min`` ... ``z_max`` for the scene's axes only: "fixed" | "slip" |
  "symmetry" (a mirror) | "clamped" (held, with the odd mirror beyond: :mod:`parmpm.grid.symmetry`)
  | "free" (default "free"); the resolved table has all ``2·dim`` keys. ``fixed_regions`` (list of
  ``{min, max}``: every node inside has ``v = 0``, e.g. a grip) and ``slip_regions`` (list of
  ``{min, max, normal}`` with ``normal`` "x" | "y" | "z": every node inside has zero velocity
  along ``normal``, a symmetry plane inside the grid); both default to none. Under
  interpolator "bspline" both are refused (a spline leans on held nodes past the region's edge:
  hold the body at a grid face) unless ``regions_with_splines`` (bool, default absent) is true,
  for a study of that error.
* ``[[walls]]`` (optional, at most 64): rigid planes (:mod:`parmpm.scene.loads`,
  :mod:`parmpm.grid.walls`): ``point`` (required), ``normal`` (required, nonzero, out of the
  wall; normalised), ``friction`` (Coulomb's μ >= 0 or "stick", default 0), ``velocity``
  (default zero: a fixed wall; m/s, |v| <= 1e6), ``time`` (a time function scaling the
  velocity; refused on a fixed wall, where it would be ignored), ``name`` (default "wall<i>"; letters, digits, ``_ -``: names its history columns).
* ``[[loads]]`` (optional, at most 256; :mod:`parmpm.loads.external`): ``kind``
  "body_force" | "point" | "traction" | "pressure" (required); ``body`` (index in [[bodies]];
  required for traction and pressure, every body when a body_force leaves it out); ``value``
  (``dim`` numbers: m/s² for body_force, N for point, Pa for traction); ``pressure`` (Pa, > 0
  pushes in; pressure only); ``at`` (point only, inside the grid: the particle nearest it at the
  start); ``region`` (``{min, max}``: traction and pressure act only on the faces inside it);
  ``normal`` (``dim`` numbers, nonzero, normalised; traction and pressure only, default absent:
  only the faces whose outward normal is within 1° of it); ``time``;
  ``name`` (default "load<i>"). A time function (``time`` of a wall or load) is a table
  ``function`` "constant" (default) | "ramp" | "smooth_step" (both with ``duration`` > 0 s) |
  "table" (with ``points``, up to 10,000 pairs ``[t, f]``, times increasing from >= 0)
  (:mod:`parmpm.loads.time_functions`).
* ``[contact]`` (optional; :mod:`parmpm.scene.contact`, :mod:`parmpm.grid.contact`): the bodies
  become separate velocity fields that meet through frictional contact instead of sharing one
  grid velocity. ``friction`` (Coulomb's μ >= 0 between fields, or "stick"; default 0),
  ``fields`` (a list of lists of body indices, every body in exactly one, at least two fields,
  at most 16; default: every body its own field, held to the same 16), ``names`` (optional:
  one per field, 1 to 40 letters, digits, ``_ -``, unused by any wall or load; they name the
  field's history columns, default "contact<k>"; no wall, probe, field or far side
  ``<name>_far`` may give a column another gives, nor ``support`` with held faces), ``normal`` (how a node's contact normal is
  found from the fields' first moments about the node: "separating", the default, the better
  separating, by the gap below, of the normal out of the field with the most mass there and
  the line between the fields' local centres of mass; "heavy" and "centroids", each of those
  alone; "gradient", out of the field whose moment points at the others most, Nairn's larger
  volume gradient; "average", all fields' moments combined as Nairn's average volume gradient),
  ``gap`` (where a node's gap between the fields is measured: "column", the default, over the
  particle domains in the node's column across the normal; "line", only where the node's own
  line along the normal crosses the domains),
  ``cracks`` (bool, default false: crack faces from the damage model, :mod:`parmpm.grid.crack`;
  every field gets a far side, where a particle goes at a node whose crack it is across; the
  default ``fields`` is then one field of all bodies, at most 8; needs a material with a damage
  model; the transfers then run the generic loops), ``crack_damage`` (0 < D <= 1,
  default 1; with ``cracks`` only: a node's crack opens when the most damaged particle reaching
  it has at least this damage). Absent: one field, as before.
* ``[manufactured]`` (optional): ``amplitude`` (> 0 m, required): drive the scene with the
  axis-aligned manufactured solution (``parmpm.loads.manufactured``; one neo-Hookean material; particles
  start on the exact field and get its body force every step).
* ``[time]``: ``end`` (> 0 s) and/or ``steps`` (int > 0), at least one; the run stops at
  whichever comes first (a missing one resolves to None). ``cfl`` (0 < cfl < 1, default 0.4),
  ``dt_max`` (> 0 s, default None: a cap on the CFL step), ``dt`` (> 0 s, default None: every
  step this long instead of the CFL one, the last shortened to end on ``end``; not with
  ``dt_max``; one warning when it is longer than the CFL step; at most 10⁹ steps to ``end``
  unless ``steps`` stops the run first), ``max_energy_growth`` (> 0 or "off", default 1.0: the run
  stops when the body holds more energy than it started with plus the work of gravity by more
  than this fraction of that; :mod:`parmpm.output.energy`).
* ``[output]``: ``every`` (simulated seconds) and/or ``every_steps``; a snapshot is due whenever
  either schedule fires. If neither is given: ``every_steps = max(1, steps // 20)`` when
  ``time.steps`` is set, else ``every = end / 20``. ``snapshots``, ``figure`` (bools, default true).
  ``domains`` (bool, default true): the particle domains as cells in the snapshots.
  ``[output.history]`` (or ``output.history = false``): ``every`` / ``every_steps`` (default
  about 200 rows per run), ``probes`` (an array of tables: ``name``, one of ``point`` /
  ``region = {min, max}`` / ``body`` / ``material``, ``field`` or ``fields``, ``stats``); see
  :mod:`parmpm.scene.history` and :mod:`parmpm.output.history` for the columns.
* ``[metrics]``: ``kind`` ("hanging_bar" | "vibrating_bar" | "tension_bar" | "manufactured" |
  "rotation" | "none", default "none"; see ``parmpm.output.metrics``), ``stop_on_separation`` (bool,
  default false; hanging_bar and tension_bar only: stop the run once the material is in more
  than one piece), ``grip`` (tension_bar only, default "grip": the material of the two box
  bodies that pull the bar; every other body is the bar),
  ``every_steps`` (default 1), ``axis`` (default: the first vibration axis for vibrating_bar,
  else ``dim − 1``, the axis along which a hanging bar's gravity acts).
* ``[decomposition]``: ``rebalance_threshold`` (>= 0, default 0.1: re-partition the patches when
  the busiest rank holds more than 1.1 × the mean particle count), ``rebalance_cooldown``
  (int >= 1, default 50: imbalance checks skipped after a re-partition that would not help).
* ``[checkpoint]``: ``every_steps`` (int >= 1), ``every`` (simulated s), ``wall_minutes``
  (wall-clock minutes) — a checkpoint is written whenever any set schedule fires (default: none);
  ``keep`` (int >= 1, default 3: older ones are deleted), ``at_end`` (bool, default false),
  ``ranks_per_file`` (``"auto"``, default: one part file per rank up to 256 ranks, then groups of
  ⌈ranks/256⌉ consecutive ranks; or an integer >= 1: each group's lowest rank writes the group's
  particles; as many as the ranks: one file; snapshots are written in the same groups). A SIGTERM or SIGINT always writes a final
  checkpoint before the run stops.

Absent optional values (``time.end``, ``time.dt_max``, ``time.dt``, ``output.every``, ``bodies.N.vibration``,
...) are ``None`` in ``Scene.data`` and omitted from ``Scene.to_toml()``.
"""
