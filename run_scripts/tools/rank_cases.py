"""The scenes whose final states must not depend on the rank count, nor change in a renovation.

:data:`CASES` (``tests/mpi/test_mpi_ranks.py`` runs them on 1-4 ranks and compares): 1D, 2D and 3D,
every interpolator, USL and MUSL, unscaled CPDI, a scene whose particles cross patch and rank
boundaries many times and that re-balances, the manufactured solution (per-particle body force,
mirror faces), a spinning disk, a damaging material, the tension bar.
:func:`renovation_cases` adds the kernel paths ``bit_identical.py`` also saves. A case is
``name: [scene, [overrides...]]``, as :mod:`save_final_states` reads it.
"""
from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
OFF = ["output.snapshots=false", "output.figure=false"]
CROSSING = str(ROOT / "tests" / "scenes" / "crossing.toml")
METHODS = ("mpm", "ugimp", "cpgimp", "cpdi")


def _cases() -> dict:
    cases = {}
    for m in METHODS:
        cases[f"1d_{m}"] = ["hanging_bar_1d", OFF + [f"method.interpolator={m}", "grid.patch_size=4",
                                                     "time.steps=60"]]
        cases[f"2d_{m}"] = ["hanging_bar", OFF + [f"method.interpolator={m}", "grid.patch_size=4",
                                                  "time.steps=40"]]
        cases[f"3d_{m}"] = ["hanging_bar_3d", OFF + [f"method.interpolator={m}", "grid.patch_size=3",
                                                     "bodies.0.ppc=2", "time.steps=8"]]
    cases["2d_cpdi_unscaled"] = ["hanging_bar", OFF + ["method.lcr=none", "grid.patch_size=4",
                                                       "time.steps=40"]]
    cases["2d_cpdi_musl"] = ["hanging_bar", OFF + ["method.update=musl", "grid.patch_size=4",
                                                   "time.steps=40"]]
    # two patches only: on 3 and 4 ranks some ranks hold nothing; with snapshots and figure on
    cases["1d_cpdi_idle_ranks"] = ["hanging_bar_1d", ["grid.patch_size=16", "time.steps=30"]]
    # CPDI2 (generic kernels): the tracked corners migrate with their particles
    cases["2d_cpdi2"] = ["hanging_bar", OFF + ["method.interpolator=cpdi2", "grid.patch_size=4",
                                               "time.steps=40"]]
    # the quadratic B-spline (generic kernels): one 2D case
    # (held at the grid's top face: B-splines refuse held node regions)
    cases["2d_bspline"] = ["hanging_bar", OFF + ["method.interpolator=bspline", "grid.patch_size=4",
                                                 "time.steps=40", "boundary.slip_regions=[]",
                                                 "grid.cells=[20, 30]", "boundary.y_max=symmetry"]]
    for m in ("cpdi", "mpm", "ugimp"):
        cases[f"crossing_{m}"] = [CROSSING, [f"method.interpolator={m}"]]
    # per-particle body force and mirror faces folded patch by patch (manufactured solution;
    # the B-spline's MUSL re-map folds the momentum again); a spinning body
    cases["2d_manufactured_cpgimp"] = ["manufactured", OFF + ["method.interpolator=cpgimp",
                                                              "method.lcr=none", "grid.patch_size=5",
                                                              "time.steps=40"]]
    cases["2d_manufactured_bspline"] = ["manufactured", OFF + ["method.interpolator=bspline",
                                                               "grid.patch_size=4",
                                                               "time.steps=40"]]
    # the odd mirror of a clamped face (1D B-spline vibrating bar, folded patch by patch)
    cases["1d_vibrating_bspline_clamped"] = ["vibrating_bar", OFF + [
        "method.interpolator=bspline", "grid.patch_size=4", "time.steps=120"]]
    cases["2d_spinning_cpdi"] = ["spinning_disk", OFF + ["grid.patch_size=6", "time.steps=60",
                                                         "metrics.every_steps=5"]]
    # APIC: the affine field migrates with its particles (the disk crosses patches)
    cases["2d_spinning_bspline_apic"] = ["spinning_disk", OFF + [
        "method.interpolator=bspline", "method.transfer=apic", "grid.patch_size=6",
        "time.steps=60", "metrics.every_steps=5"]]
    # a damaging material (stretch-driven damage degrading the stress), specialised 2D kernels
    # and the generic 1D ones
    damage = "materials.bar.damage={onset=1.05, fracture=1.6}"
    cases["2d_cpdi_damage"] = ["hanging_bar", OFF + [damage, "grid.patch_size=4", "time.steps=60"]]
    cases["2d_cpdi_freeze"] = ["hanging_bar", OFF + [
        "materials.bar.damage={onset=1.02, fracture=1.5, freeze=0.3}", "grid.patch_size=4",
        "time.steps=150", "metrics.stop_on_separation=false"]]
    cases["1d_cpdi_damage"] = ["hanging_bar_1d", OFF + [damage, "grid.patch_size=4",
                                                        "time.steps=60"]]
    # no metrics: every rank counts the particles per patch axis by axis and builds only its
    # own (parmpm.particles.seeding); the same run as 2d_cpdi, whose metrics make every rank seed all
    cases["2d_cpdi_no_metrics"] = ["hanging_bar", OFF + ["metrics.kind=none", "grid.patch_size=4",
                                                         "time.steps=40"]]
    # the tension bar: grips, a weak band, domains freezing; separation counted across ranks
    cases["2d_tension_bar"] = ["tension_bar", OFF + ["grid.patch_size=8"]]
    # a CSG body (box minus disk: the plate-with-hole example), seeded patch by patch
    cases["2d_csg_plate_with_hole"] = [str(ROOT / "docs" / "examples" / "plate_with_hole.toml"),
                                       OFF + ["grid.patch_size=8", "time.steps=40"]]
    # plastic materials (the plastic pass after G2P, its state rows migrating with their
    # particles): J2 with linear hardening on the 2D hanging bar, yielding at the top; 3D J2
    # through the B-spline kernels; Drucker-Prager (its cone and apex returns) in 1D and 2D
    j2 = ['materials.bar.model="j2"', "materials.bar.youngs_modulus=1e7",
          "materials.bar.yield_stress=7e5", "materials.bar.hardening_modulus=5e6"]
    cases["2d_cpdi_j2"] = ["hanging_bar", OFF + j2 + ["grid.patch_size=4", "time.steps=60"]]
    cases["3d_bspline_j2"] = ["hanging_bar_3d", OFF + j2 + ["materials.bar.yield_stress=2e4",
        "method.interpolator=bspline", "grid.patch_size=3", "bodies.0.ppc=2", "time.steps=8",
        "boundary.slip_regions=[]", "grid.cells=[9, 15, 9]", "boundary.y_max=symmetry"]]
    dp = ['materials.bar.model="drucker_prager"', "materials.bar.friction_angle=30",
          "materials.bar.cohesion=2e5", "materials.bar.dilatancy_angle=10"]
    cases["2d_cpdi_drucker_prager"] = ["hanging_bar", OFF + dp + ["grid.patch_size=4",
                                                                  "time.steps=60"]]
    cases["1d_mpm_drucker_prager"] = ["hanging_bar_1d", OFF + dp + [
        "method.interpolator=mpm", "grid.patch_size=4", "time.steps=60",
        "metrics.stop_on_separation=false"]]
    return cases


CASES = _cases()


def renovation_cases() -> dict:
    """The rank-independence cases plus the extra kernel paths :mod:`bit_identical` checks: linear
    elasticity and MUSL for every interpolator in 2D and 3D, 3D damage with freezing, 3D unscaled
    CPDI and the vibrating bar (48 cases)."""
    out = dict(CASES)
    bar3 = ["grid.patch_size=3", "bodies.0.ppc=2", "time.steps=8"]
    for m in ("mpm", "ugimp", "cpgimp", "cpdi"):
        interp = f"method.interpolator={m}"
        for law_or_update, tag in (("materials.bar.model=linear_elastic", "linear"),
                                   ("method.update=musl", "musl")):
            out[f"2d_{m}_{tag}"] = ["hanging_bar", OFF + [law_or_update, interp, "grid.patch_size=4",
                                                          "time.steps=40"]]
            out[f"3d_{m}_{tag}"] = ["hanging_bar_3d", OFF + [law_or_update, interp] + bar3]
    out["3d_cpdi_damage"] = ["hanging_bar_3d", OFF + [
        "materials.bar.damage={onset=1.02, fracture=1.5, freeze=0.3}", "grid.patch_size=3",
        "bodies.0.ppc=2", "time.steps=30", "metrics.stop_on_separation=false"]]
    out["3d_cpdi_unscaled"] = ["hanging_bar_3d", OFF + ["method.lcr=none"] + bar3]
    out["vibrating_bar"] = ["vibrating_bar", OFF + ["time.steps=100"]]
    return out


# bodies read from files (issue 30): a mesh's quadrature points (two rings from Gmsh groups,
# each particle its own volume) and a particle file (two materials, velocities and F from the file)
CASES["2d_mesh_rings"] = [str(ROOT / "docs" / "examples" / "rings_from_mesh.toml"),
                          OFF + ["time.steps=40", "output.history.enabled=false"]]
CASES["2d_particle_file_blob"] = [str(ROOT / "tests" / "data" / "spinning_blob.toml"),
                                  OFF + ["output.history.enabled=false"]]

# walls and loads (issue 30): a block sliding on a 30-degree plane with friction, a block
# pressed by a moving plate onto a held base (the walls' marks summed over the ghost layers), the
# Kirsch plate pulled by a traction on surface faces gathered from every rank
EXAMPLES = ROOT / "docs" / "examples"
CASES["2d_wall_friction"] = [str(EXAMPLES / "sliding_block.toml"),
                             OFF + ["grid.patch_size=6", "time.steps=60"]]
CASES["2d_wall_plate"] = [str(EXAMPLES / "pressed_block.toml"),
                          OFF + ["grid.patch_size=4", "time.steps=60"]]
CASES["2d_traction_kirsch"] = [str(EXAMPLES / "kirsch_plate.toml"),
                               OFF + ["grid.patch_size=8", "time.steps=40"]]

# contact between velocity fields (issue 31): two rings colliding (frictionless, from a mesh),
# two spheres in an oblique collision with friction (3D) and a block sliding on a held block
# with friction (USL cpdi and MUSL ugimp): each field's sums, first moments and per-node
# extremes over the ghost layers
CASES["2d_contact_rings"] = [str(EXAMPLES / "rings_contact.toml"),
                             OFF + ["time.steps=400", "output.history.every_steps=50"]]
CASES["2d_contact_slide"] = [str(EXAMPLES / "block_on_block.toml"),
                             OFF + ["grid.patch_size=5", "time.steps=150"]]
CASES["3d_contact_spheres"] = [str(EXAMPLES / "spheres_contact.toml"),
                               OFF + ["grid.patch_size=4", "time.steps=120"]]
CASES["2d_contact_slide_ugimp"] = [str(EXAMPLES / "block_on_block.toml"),
                                   OFF + ["grid.patch_size=5", "time.steps=150",
                                          "method.interpolator=ugimp"]]

# crack faces from the damage model (issue 31): the 1D bar that breaks and is pushed back
# together, and the tension bar separating without the domain freeze (each node's crack normal
# from sums and a maximum over the ghost layers, every particle's field chosen per node)
CASES["1d_crack_broken_bar"] = [str(EXAMPLES / "broken_bar.toml"),
                                OFF + ["grid.patch_size=10", "output.history.every_steps=20"]]
CASES["2d_crack_tension_bar"] = ["tension_bar", OFF + ["grid.patch_size=8", "contact.cracks=true",
                                                       "materials.band.damage.freeze=never",
                                                       "materials.bar.damage.freeze=never"]]
CASES["3d_crack_hanging_bar"] = ["hanging_bar_3d", OFF + [
    "materials.bar.damage={onset=1.02, fracture=1.5, freeze=0.3}", "grid.patch_size=3",
    "bodies.0.ppc=2", "time.steps=30", "metrics.stop_on_separation=false", "contact.cracks=true",
    "contact.crack_damage=0.01"]]
