"""The files whose bytes make an object of a file: a URDF's meshes, a ``.gltf``'s buffers; and whether any of
them changed since a time."""

from __future__ import annotations

import json
from pathlib import Path
from urllib.parse import unquote

from planner.errors import InputError
from planner.specs.urdf_objects import URDF_SUFFIX, read_urdf_object


def object_files(source: Path, geometry: str = "collision") -> list[Path]:
    """The files whose bytes make the object of the file ``source``: itself, a URDF's mesh files (of its
    ``geometry`` elements: :func:`~planner.specs.urdf_objects.read_urdf_object`), and the buffer files each
    ``.gltf`` of these names (:func:`gltf_buffers`; they may not exist). A URDF that does not read is an
    InputError."""
    files = [source, *(read_urdf_object(source, geometry).files if source.suffix.lower() == URDF_SUFFIX else ())]
    return [*files, *(b for f in files for b in gltf_buffers(f))]


def edited_since(source: Path, finished: float | None, geometry: str = "collision") -> bool:
    """Whether the object of the file ``source`` (:func:`object_files`: a ``.gltf``'s buffers, a URDF's meshes of
    its ``geometry`` elements) may have changed since ``finished`` (its object's last unit's end [s];
    :meth:`~planner.db.store.Database.last_finished`): modified from that second on, no time known, or no file to
    read. A copy that keeps an older modification time is not seen."""
    try:
        files = object_files(source, geometry)
        buffers = {b for f in files for b in gltf_buffers(f)}  # each spelling of a buffer's name: one may be missing
        return finished is None or any(f.stat().st_mtime >= finished for f in files if f not in buffers or f.exists())
    except (OSError, InputError):
        return True


def sidecar_changed(source: Path, finished: float | None) -> bool:
    """Whether the sidecar of the file ``source`` (``banana.toml`` beside ``banana.obj``) may have changed since
    ``finished`` [s]: modified from that second on, or, where there is none now, its folder changed since (a
    sidecar removed: its values, a centre of mass among them, no more). Its folder also changes when any other
    file there is made or removed (a database's journal beside it): then the object is compared, at some cost."""
    from planner.specs.objects import mesh_sidecar

    try:
        found = mesh_sidecar(source)
        paths = [found] if found is not None else list(dict.fromkeys((source.parent, source.resolve().parent)))
        return finished is None or any(p.stat().st_mtime >= finished for p in paths)
    except (OSError, InputError):
        return True


def gltf_buffers(path: Path) -> list[Path]:
    """The files the buffers of a ``.gltf`` name, where its geometry is
    (relative to it, each as written and URL-decoded: loaders differ; embedded
    ``data:`` buffers are in the file itself); [] for any other file, or one
    that is not glTF JSON (its loader says why)."""
    if path.suffix.lower() != ".gltf":
        return []
    try:
        data = json.loads(path.read_bytes())
    except (OSError, ValueError):
        return []
    buffers = data.get("buffers", []) if isinstance(data, dict) else []
    uris = [b.get("uri") for b in buffers if isinstance(b, dict)] if isinstance(buffers, list) else []
    names = [u for u in uris if isinstance(u, str) and u and not u.startswith("data:")]
    return [path.parent / n for n in dict.fromkeys(n for u in names for n in (u, unquote(u)))]
