"""STL → OBJ conversion, done once per mesh and cached in the user cache directory.

Drake's Meshcat and proximity geometry want OBJ (or glTF) files; example-robot-data ships STL.
Each mesh is converted with trimesh the first time it is needed and written atomically (a temporary
file in the same directory, then ``os.replace``), so concurrent runs never see a partial file.
The cache lives in ``$SOTDRAKE_CACHE`` or ``$XDG_CACHE_HOME/sotdrake`` (default ``~/.cache/sotdrake``),
keyed by the source file's size and modification time.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from pathlib import Path


def cache_root() -> Path:
    """The directory where converted meshes are kept."""
    if "SOTDRAKE_CACHE" in os.environ:
        return Path(os.environ["SOTDRAKE_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(Path.home(), ".cache")
    return Path(base) / "sotdrake"


def obj_for_stl(stl_path: Path) -> Path:
    """Path of the OBJ conversion of ``stl_path``, converting it now if it is not cached."""
    stl_path = Path(stl_path)
    stat = stl_path.stat()
    key = hashlib.sha1(f"{stl_path.resolve()}|{stat.st_size}|{stat.st_mtime_ns}".encode()).hexdigest()
    target = cache_root() / "meshes" / key[:2] / f"{stl_path.stem}-{key[:12]}.obj"
    if target.exists():
        return target
    import trimesh  # imported here: only needed the first time a mesh is converted

    mesh = trimesh.load(stl_path, file_type="stl", force="mesh")
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=target.parent, suffix=".obj.tmp")
    try:
        with os.fdopen(fd, "w") as f:
            f.write(trimesh.exchange.obj.export_obj(mesh, include_normals=False))
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return target
