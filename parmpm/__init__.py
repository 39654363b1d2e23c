"""parmpm — explicit, patch-decomposed Material Point Method with CPDI domain scaling.

The public API (scripts and tests import from here, not from internals)::

    import parmpm
    scene = parmpm.load_scene("hanging_bar", overrides=["method.interpolator=mpm"])
    summary = parmpm.Simulation(scene, out_dir="parmpm-out/hb").run()

The packages are the layers, listed top to bottom; a package imports only packages below it
(``tests/project/test_import_contract.py`` derives the allowed arrows from :data:`LAYERS`):

=============  =========================================================================
``cli``        the command line: parser, commands, launching under MPI, benchmarks
``driver``     a run: set-up, the run loop, what happens between steps (output,
               checkpoints, measures, signals), compiling kernels first
``scene``      TOML in, a validated and resolved scene out; built-in scenes
``output``     what a run reports: history, energy ledger, metrics, particle domains
``step``       the explicit step as ordered phases (USL or MUSL)
``particles``  the particle store, its canonical order, locating patches, seeding bodies into it
``loads``      forcings applied to bodies (the manufactured solution)
``transfer``   particle ↔ grid transfers: generic loops, 2D/3D kernels, update orders
``shapes``     interpolators: weights and gradients (hat, GIMP, B-spline, CPDI, CPDI2)
``grid``       the nodal update, boundary and symmetry conditions, patch-box arithmetic
``materials``  constitutive laws, damage, kinematics of one particle
``geometry``   body primitives: placement and inside tests (pure numpy)
``exact``      exact solutions parmpm is verified against (pure numpy)
``io``         file formats only: XDMF/HDF5 snapshots, checkpoints, history, summary
``core``       what every layer shares: JIT flags and cache, errors, logging, records
=============  =========================================================================

``decomposition`` (patches, ghost exchange, migration over MPI) is a separate, physics-free
package that any layer may use; it never imports parmpm.
"""
from parmpm.core.errors import ParmpmError, SceneError, SimulationError
from parmpm.core.version import __version__
from parmpm.scene.load import Scene, builtin_scenes, load_scene, parse_lcr

#: the layers, top to bottom (see the table above)
LAYERS = ("cli", "driver", "scene", "output", "step", "particles", "loads", "transfer", "shapes",
          "grid", "materials", "geometry", "exact", "io", "core")


def __getattr__(name):
    # Simulation pulls in numba kernels: import it lazily so `parmpm scenes` stays fast.
    if name == "Simulation":
        from parmpm.driver.simulation import Simulation
        return Simulation
    if name in ("domain_corners", "domain_sizes", "domain_vectors"):
        from parmpm.output import domains
        return getattr(domains, name)
    raise AttributeError(f"module 'parmpm' has no attribute {name!r}")


def run(source, overrides=(), out_dir=None, quiet=True, overwrite=False) -> dict:
    """Load a scene (built-in name or TOML path), run it on this process, return its summary.
    ``out_dir`` holding another run or files parmpm did not write is refused unless
    ``overwrite`` (:mod:`parmpm.io.run_folder`)."""
    from parmpm.driver.simulation import Simulation
    return Simulation(load_scene(source, overrides), out_dir, quiet=quiet, overwrite=overwrite).run()


__all__ = ["Scene", "Simulation", "run", "domain_corners", "domain_sizes", "domain_vectors",
           "load_scene", "builtin_scenes", "parse_lcr", "ParmpmError", "SceneError",
           "SimulationError", "__version__", "LAYERS"]
