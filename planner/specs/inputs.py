"""Turning command-line object arguments into a list of objects.

Accepted, in any mix:

- a built-in name (``mug``), ``random_NNN``, or a mesh file path;
- ``builtin:all`` (every registry object), ``builtin:random`` (all 1,000
  generated objects), ``builtin:random:20`` (the first 20),
  ``builtin:random:100-149`` (a range, inclusive);
- a folder (its mesh files, recursively) or a glob (``meshes/**/*.obj``);
- ``@list.txt``: a manifest, one object per line, optionally followed by a
  scale; ``#`` starts a comment; relative paths are relative to the manifest.

Mesh files are named by their file stem; when two files of one run share a
stem, their parent folders are prefixed until the names differ.
"""

from __future__ import annotations

import glob
from dataclasses import dataclass
from pathlib import Path

from planner.errors import InputError
from planner.specs.objects import MESH_SUFFIXES, RANDOM_COUNT, RANDOM_PREFIX, builtin_specs, resolve_spec


@dataclass(frozen=True)
class ObjectRef:
    """One object of a run: how to load it and the name it is stored under."""

    source: str  # built-in name or mesh path
    scale: float | None = None
    label: str | None = None  # database name (None: the default one)

    @property
    def name(self) -> str:
        return self.label or resolve_spec(self.source, scale=self.scale).name


def expand(args: list[str] | tuple[str, ...], scale: float | None = None) -> list[ObjectRef]:
    refs: list[ObjectRef] = []
    for arg in args:
        refs += _expand_one(arg, scale)
    return _unique_labels(refs)


def _expand_one(arg: str, scale: float | None) -> list[ObjectRef]:
    if arg == "builtin:all":
        return [ObjectRef(name) for name in builtin_specs()]
    if arg.startswith("builtin:random"):
        return [ObjectRef(f"{RANDOM_PREFIX}{i:03d}") for i in _random_range(arg)]
    if arg.startswith("@"):
        return _manifest(Path(arg[1:]), scale)
    path = Path(arg).expanduser()
    if path.is_dir():
        files = sorted(p for p in path.rglob("*") if p.suffix.lower() in MESH_SUFFIXES and p.is_file())
        if not files:
            raise InputError(f"{path}: folder holds no mesh files ({', '.join(MESH_SUFFIXES)})")
        return [ObjectRef(str(p.resolve()), scale) for p in files]
    if any(c in arg for c in "*?["):
        files = sorted(Path(p) for p in glob.glob(str(path), recursive=True)
                       if Path(p).suffix.lower() in MESH_SUFFIXES)
        if not files:
            raise InputError(f"'{arg}': no mesh files match")
        return [ObjectRef(str(p.resolve()), scale) for p in files]
    return [ObjectRef(arg, scale)]


def _random_range(arg: str) -> range:
    rest = arg[len("builtin:random"):]
    if not rest:
        return range(RANDOM_COUNT)
    spec = rest.lstrip(":")
    try:
        if "-" in spec:
            lo, hi = (int(v) for v in spec.split("-", 1))
            result = range(lo, hi + 1)
        else:
            result = range(int(spec))
    except ValueError:
        raise InputError(f"'{arg}': use builtin:random, builtin:random:COUNT or builtin:random:FIRST-LAST") from None
    if not result or result.start < 0 or result.stop > RANDOM_COUNT:
        raise InputError(f"'{arg}': range must lie within 0-{RANDOM_COUNT - 1}")
    return result


def _manifest(path: Path, scale: float | None) -> list[ObjectRef]:
    if not path.is_file():
        raise InputError(f"{path}: manifest not found")
    refs = []
    for number, raw in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        parts = line.split()
        if len(parts) > 2:
            raise InputError(f"{path}:{number}: expected 'OBJECT [SCALE]', got '{raw.strip()}'")
        item_scale = scale
        if len(parts) == 2:
            try:
                item_scale = float(parts[1])
            except ValueError:
                raise InputError(f"{path}:{number}: scale '{parts[1]}' is not a number") from None
        source = parts[0]
        candidate = (path.parent / source)
        if Path(source).suffix.lower() in MESH_SUFFIXES and not Path(source).is_absolute():
            source = str(candidate.resolve())
        refs.append(ObjectRef(source, item_scale))
    if not refs:
        raise InputError(f"{path}: manifest lists no objects")
    return refs


def _unique_labels(refs: list[ObjectRef]) -> list[ObjectRef]:
    """Drop repeats; give mesh files sharing a stem distinct names."""
    seen: dict[tuple[str, float | None], ObjectRef] = {}
    for ref in refs:
        seen.setdefault((ref.source, ref.scale), ref)
    refs = list(seen.values())
    files = [r for r in refs if Path(r.source).suffix.lower() in MESH_SUFFIXES]
    depth = 0
    while True:
        labels = {r.source: _label(Path(r.source), depth) for r in files}
        if len(set(labels.values())) == len(labels) or depth > 8:
            break
        depth += 1
    if depth == 0:
        return refs
    return [ObjectRef(r.source, r.scale, labels[r.source]) if r.source in labels else r for r in refs]


def _label(path: Path, depth: int) -> str:
    parts = path.with_suffix("").parts
    return "/".join(parts[-(depth + 1):])
