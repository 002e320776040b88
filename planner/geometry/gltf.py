"""What keeps a glTF file (``.gltf``, ``.glb``) from loading, in words, for the one-line error of a file trimesh
could not read: a ``.gltf`` copied without the buffer files its geometry is in, or geometry compressed by an
extension trimesh reads only with a package this planner does not install (Draco) or not at all (meshopt).
"""

from __future__ import annotations

import importlib.util
import json
import struct
from pathlib import Path
from urllib.parse import unquote

#: glTF extensions that compress geometry: the module trimesh decodes each with (None: none), and what to do.
#: Undecoded, trimesh's Draco geometry is placeholder zeros ('every triangle is degenerate' said a valid file).
COMPRESSION = {
    "KHR_draco_mesh_compression": ("DracoPy", "Draco-compressed (KHR_draco_mesh_compression): pip install DracoPy, "
                                              "with which trimesh reads it, or export it uncompressed"),
    "EXT_meshopt_compression": (None, "meshopt-compressed (EXT_meshopt_compression), which trimesh cannot read: "
                                      "export it uncompressed"),
}
#: A binary glTF's header: magic, version, length; then its first chunk's length and type (JSON).
_GLB_HEADER = struct.Struct("<4sII")
_CHUNK_HEADER = struct.Struct("<I4s")


def gltf_problem(path: Path) -> str:
    """Why ``path`` cannot be read as glTF, said to its user, before it is read; '' when nothing here tells (not
    glTF, its JSON unreadable: the loader's own message stands)."""
    data = _gltf_json(path)
    if data is None:
        return ""
    used = [e for key in ("extensionsRequired", "extensionsUsed") if isinstance(data.get(key), list)
            for e in data[key] if isinstance(e, str) and e in COMPRESSION]
    for extension in dict.fromkeys(used):
        module, advice = COMPRESSION[extension]
        if (module is None or importlib.util.find_spec(module) is None) and not _draco_fallback(data, extension):
            return f"its geometry is {advice}"
    if _normalized_positions(data):
        return ("its positions are quantized to normalized integers (KHR_mesh_quantization), which trimesh reads "
                "unscaled (a 5 cm box read 2.6 km across): export it with float positions (gltf-transform dequantize)")
    buffers = data.get("buffers", [])
    uris = [b.get("uri") for b in buffers if isinstance(b, dict)] if isinstance(buffers, list) else []
    missing = [u for u in uris if isinstance(u, str) and u and not u.startswith("data:")
               and not any((path.parent / n).is_file() for n in (u, unquote(u)))]
    if missing:
        return (f"the buffer file{'s' if len(missing) > 1 else ''} holding its geometry, {', '.join(missing)}, "
                f"{'are' if len(missing) > 1 else 'is'} not beside it: copy {'them' if len(missing) > 1 else 'it'} "
                "with the .gltf, or export a .glb (one file)")
    return ""


def _draco_fallback(data: dict, extension: str) -> bool:
    """Whether a file Draco-compresses its geometry as an option only: the extension used, not required, and
    every compressed primitive's positions also stored plain (an accessor with a ``bufferView``), which trimesh
    reads without DracoPy (the glTF extension's fallback)."""
    required = data.get("extensionsRequired")
    if extension != "KHR_draco_mesh_compression" or (isinstance(required, list) and extension in required):
        return False
    accessors = data.get("accessors", [])
    meshes = data.get("meshes", [])
    if not isinstance(accessors, list) or not isinstance(meshes, list):
        return False
    compressed = [p for m in meshes if isinstance(m, dict) for p in m.get("primitives", [])
                  if isinstance(p, dict) and extension in (p.get("extensions") or {})]
    positions = [(p.get("attributes") or {}).get("POSITION") for p in compressed]
    return all(isinstance(i, int) and 0 <= i < len(accessors) and isinstance(accessors[i], dict)
               and "bufferView" in accessors[i] for i in positions)


def _normalized_positions(data: dict) -> bool:
    """Whether a primitive's POSITION accessor holds normalized integers (not floats: componentType 5126)."""
    accessors = data.get("accessors", [])
    meshes = data.get("meshes", [])
    if not isinstance(accessors, list) or not isinstance(meshes, list):
        return False
    found = [p.get("attributes", {}).get("POSITION") for m in meshes if isinstance(m, dict)
             for p in m.get("primitives", []) if isinstance(p, dict) and isinstance(p.get("attributes"), dict)]
    return any(isinstance(i, int) and 0 <= i < len(accessors) and isinstance(accessors[i], dict)
               and accessors[i].get("normalized") is True and accessors[i].get("componentType") != 5126 for i in found)


def _gltf_json(path: Path) -> dict | None:
    """The JSON of a ``.gltf`` or of a ``.glb``'s first chunk; None if ``path`` is neither, or unreadable."""
    suffix = path.suffix.lower()
    try:
        if suffix == ".gltf":
            data = json.loads(path.read_bytes())
        elif suffix == ".glb":
            with path.open("rb") as f:
                head = f.read(_GLB_HEADER.size + _CHUNK_HEADER.size)
                magic, _, _ = _GLB_HEADER.unpack_from(head)
                length, kind = _CHUNK_HEADER.unpack_from(head, _GLB_HEADER.size)
                if magic != b"glTF" or kind != b"JSON":
                    return None
                data = json.loads(f.read(length))
        else:
            return None
    except (OSError, ValueError, struct.error):
        return None
    return data if isinstance(data, dict) else None
