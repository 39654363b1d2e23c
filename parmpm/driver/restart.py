"""A restart: the checkpoint to continue from and the scene it continues with.

:func:`open_checkpoint` reads the scene a checkpoint stores, applies the ``--set`` overrides a
restart allows (:mod:`parmpm.driver.restart_keys`) and makes sure every rank continues the same
checkpoint with the same scene; :func:`parmpm.driver.set_up.set_up` then reads the particles back.
The checkpoint owns the run's state: the bodies' global-id ranges and what the body files gave
come from its records (:mod:`parmpm.scene.recorded_files`), so a restart works with those files
changed, moved or deleted.
"""
from __future__ import annotations

from parmpm.core.collective import agree
from parmpm.core.errors import ParmpmError
from parmpm.driver.restart_keys import check_restart
from parmpm.io.checkpoint import CheckpointReader, attrs_digest
from parmpm.scene.agreement import check_same_scene
from parmpm.scene.load import scene_from_toml
from parmpm.scene.recorded_files import remember


def open_checkpoint(path, overrides, comm):
    """(scene, reader) of the run saved in ``path``: its stored scene with ``overrides`` applied
    (e.g. ``time.end=...``; only the keys :mod:`parmpm.driver.restart_keys` allows, recorded in
    ``scene.restart``); the caller closes the reader. Collective under ``comm``: a rank's problem
    is raised on every rank, and the ranks must continue the same checkpoint with the same scene
    (:func:`parmpm.scene.agreement.check_same_scene`)."""
    reader, scene, problem = None, None, None
    try:
        reader = CheckpointReader(path, warn=comm is None or comm.Get_rank() == 0)
        try:  # what the run read from its body files: the restart needs none of them
            remember(reader.state.get("bodies"))
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise ParmpmError(f"checkpoint '{path}': damaged: its body records do not read "
                              f"({type(exc).__name__}: {exc})") from None
        text = str(reader.attrs["scene"])
        stored = scene_from_toml(text, f"{path}")
        scene = scene_from_toml(text, f"{path}", overrides)
        if scene.dim != int(reader.attrs["dim"]):
            raise ParmpmError(f"checkpoint '{path}' holds a {int(reader.attrs['dim'])}D run; "
                              f"dim cannot change on restart (got dim = {scene.dim})")
        check_restart(path, stored, scene, overrides, int(reader.attrs["step"]),
                      float(reader.attrs["time"]))
    except ParmpmError as exc:
        if comm is None:
            if reader is not None:
                reader.close()
            raise
        problem = str(exc)
    except BaseException:
        if reader is not None:
            reader.close()
        raise
    try:
        if comm is not None:
            agree(comm, problem, root=None)
            # the same checkpoint (its attributes' digest covers its data's) and the same scene
            check_same_scene(comm, scene, f"step {int(reader.attrs['step'])}, attributes "
                             f"{attrs_digest(reader.attrs)[:12]}", what=f"'{path}'")
    except BaseException:
        if reader is not None:
            reader.close()
        raise
    return scene, reader
