"""parmpm — explicit, patch-decomposed Material Point Method with CPDI domain scaling.

The public API (scripts and tests import from here, not from internals)::

    import parmpm
    scene = parmpm.load_scene("hanging_bar", overrides=["method.interpolator=mpm"])
    summary = parmpm.Simulation(scene, out_dir="parmpm-out/hb").run()
"""
from parmpm.errors import ParmpmError, SceneError, SimulationError
from parmpm.scene import Scene, builtin_scenes, load_scene, parse_lcr

__version__ = "0.1.0"


def __getattr__(name):
    # Simulation pulls in numba kernels: import it lazily so `parmpm scenes` stays fast.
    if name == "Simulation":
        from parmpm.simulation import Simulation
        return Simulation
    if name == "run":
        return run
    if name in ("domain_corners", "domain_sizes", "domain_vectors"):
        from parmpm import domains
        return getattr(domains, name)
    raise AttributeError(f"module 'parmpm' has no attribute {name!r}")


def run(source, overrides=(), out_dir=None, quiet=True, overwrite=False) -> dict:
    """Load a scene (built-in name or TOML path), run it on this process, return its summary.
    ``out_dir`` holding another run is refused unless ``overwrite`` (:mod:`parmpm.io.run_folder`)."""
    from parmpm.simulation import Simulation
    return Simulation(load_scene(source, overrides), out_dir, quiet=quiet, overwrite=overwrite).run()


__all__ = ["Scene", "Simulation", "run", "domain_corners", "domain_sizes", "domain_vectors", "load_scene", "builtin_scenes", "parse_lcr",
           "ParmpmError", "SceneError", "SimulationError", "__version__"]
