"""STL/COLLADA → OBJ conversion, done once per mesh and cached in the user cache directory.

Drake's Meshcat and proximity geometry want OBJ (or glTF) files; example-robot-data ships STL and
COLLADA (``.dae``, read with pycollada through trimesh; the scene's node transforms are applied,
materials are not kept).
Each mesh is converted with trimesh the first time it is needed and written atomically (a temporary
file in the same directory, then ``os.replace``), so concurrent runs never see a partial file.
The cache lives in ``$SOTDRAKE_CACHE`` or ``$XDG_CACHE_HOME/sotdrake`` (default ``~/.cache/sotdrake``),
keyed by the source file's size and modification time.
"""

from __future__ import annotations

import hashlib
import logging
import os
import tempfile
from pathlib import Path

import numpy as np

from ..exceptions import InvalidInput, RobotDescriptionError, os_reason

log = logging.getLogger(__name__)


def cache_root() -> Path:
    """The directory where converted meshes are kept."""
    if "SOTDRAKE_CACHE" in os.environ:
        return Path(os.environ["SOTDRAKE_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(Path.home(), ".cache")
    return Path(base) / "sotdrake"


#: Changes when the conversion does, so that older cached files are not reused.
_FORMAT = 2


def obj_for_mesh(mesh_path: Path) -> Path:
    """Path of the OBJ conversion of an STL or COLLADA mesh, converting it now if not cached."""
    source = Path(mesh_path)
    file_type = source.suffix.lower().lstrip(".")
    if file_type not in ("stl", "dae"):
        raise InvalidInput(f"{source}: only STL and COLLADA (.dae) meshes are converted")
    stat = source.stat()
    key = hashlib.sha1(f"{source.resolve()}|{stat.st_size}|{stat.st_mtime_ns}|{_FORMAT}".encode()).hexdigest()
    target = cache_root() / "meshes" / key[:2] / f"{source.stem}-{key[:12]}.obj"
    if target.exists():
        return target
    import trimesh  # imported here: only needed the first time a mesh is converted

    try:
        mesh = trimesh.load(source, file_type=file_type, force="mesh")
    except Exception as error:  # (each reader has its own errors: pycollada's, numpy's, struct's …)
        raise RobotDescriptionError(f"{source}: the mesh does not load ({type(error).__name__}: {error})") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0 or not np.isfinite(mesh.vertices).all():
        if file_type == "stl":  # (an STL is triangles only: none read is a broken file)
            raise RobotDescriptionError(f"{source}: the mesh has no triangle or a non-finite vertex (an empty, truncated "
                                        "or corrupt file)")
        # A COLLADA file may hold what the converter does not read (ANYmal's feet): the link is not drawn.
        log.warning("%s: no triangle read from this COLLADA mesh: its link is not drawn", source)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=target.parent, suffix=".obj.tmp")
    except OSError as error:
        raise InvalidInput(f"the mesh cache {str(cache_root())!r} cannot hold {source.name}'s conversion "
                           f"({os_reason(error)}): set SOTDRAKE_CACHE to a writable folder") from None
    try:
        with os.fdopen(fd, "w") as f:
            # Geometry only: a material library would name a file that is not written.
            f.write(trimesh.exchange.obj.export_obj(mesh, include_normals=False, include_texture=False,
                                                    write_texture=False))
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return target


#: The name this function had when only STL was converted.
obj_for_stl = obj_for_mesh
