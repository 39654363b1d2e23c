"""Bodies read from files (issue 30): a volume mesh (``shape = "mesh"``), a closed surface
(``shape = "surface"``, 3D) or listed particles (``shape = "particles"``) — their scene keys
(:mod:`.keys`) and what the files hold, read once per process (:mod:`.contents`).

The resolved scene holds only the file's absolute path, the body's small keys and what the run
read of the file (its size and SHA-256): it is written as ``scene.toml`` and stored in
checkpoints, so it must stay TOML. Whatever needs the file's contents — the schema's "inside the
grid" check, :meth:`parmpm.scene.records.Body.bounds`, the overlap check, the memory estimate,
seeding — asks this package. A relative ``file`` is relative to the scene file's folder (a
scene given as text or a built-in: the working directory).
"""
from parmpm.scene.body_files.contents import (Listed, bounds, count, deferred_element_checks,
                                              inside, listed, listed_volume, surface, volume_mesh)
from parmpm.scene.body_files.keys import (FILE_DIMS, FILE_KEYS, MAX_MESH_PARTICLES, MAX_SPLIT,
                                          check_file_body, files_read, scene_folder)

__all__ = ["FILE_DIMS", "FILE_KEYS", "MAX_MESH_PARTICLES", "MAX_SPLIT", "Listed", "bounds",
           "check_file_body", "count", "deferred_element_checks", "files_read", "inside", "listed",
           "listed_volume", "scene_folder", "surface", "volume_mesh"]
