"""Turning command-line object arguments into a list of objects.

Accepted, in any mix:

- a built-in name (``mug``), ``random_NNN``, a mesh file or a URDF file path;
- ``builtin:all`` (every registry object), ``builtin:random`` (all 1,000
  generated objects), ``builtin:random:20`` (the first 20),
  ``builtin:random:100-149`` (a range, inclusive);
- a folder (its mesh and URDF files, recursively, hidden ones and ``__MACOSX/`` skipped) or a glob
  (``meshes/**/*.obj``); a mesh file that a URDF of the folder or glob names is left to it: each object
  once, with its URDF's scale, placement, mass and friction;
- ``@list.txt``: a manifest, one object per line, optionally followed by a
  scale and ``key=value`` columns (``scale=``, ``mass=`` [kg] or
  ``density=`` [kg/m^3], ``friction=``, ``up=``: ``+y``, ``-z``, ...; ``com=`` [m] x,y,z in the object
  frame; a URDF's ``geometry=visual``), e.g. ``banana.obj 1 mass=0.066
  friction=0.8``; ``#`` starts a comment; a path with blanks or ``#`` goes in
  double quotes (``"my meshes/box #2.obj" mass=0.3``); relative paths are relative
  to the manifest. A line's values win over the run's (``--scale``, ``--mass`` ...).

Mesh and URDF files are named by their file stem; when two files of one run share a
stem, their parent folders are prefixed until the names differ, and where
only their suffixes differ (``part.obj``, ``part.stl``) the names keep them.
"""

from __future__ import annotations

import glob
import math
import os
import shlex
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path

from planner.errors import InputError
from planner.specs.objects import (
    MESH_SUFFIXES,
    OBJECT_SUFFIXES,
    RANDOM_COUNT,
    RANDOM_PREFIX,
    builtin_specs,
    is_registered,
    resolve_spec,
)
from planner.specs.physical import NO_PHYSICAL, PHYSICAL_KEYS, Physical
from planner.specs.toml import decode_text
from planner.specs.urdf_objects import URDF_SUFFIX, named_meshes

#: What a manifest line holds.
MANIFEST_LINE = ("OBJECT [SCALE] [scale=S] [mass=KG | density=KG_M3] [friction=MU] [up=AXIS] [com=X,Y,Z] "
                 "[geometry=visual]")


@dataclass(frozen=True)
class ObjectRef:
    """One object of a run: how to load it and the name it is stored under."""

    source: str  # built-in name, mesh or URDF path
    scale: float | None = None
    label: str | None = None  # database name (None: the default one)
    physical: Physical = NO_PHYSICAL  # the user's mass or density, friction and up (None: the object's own)
    manifest: str | None = None  # the @manifest whose line gave it (its mtime: the line's values edited since)

    @property
    def name(self) -> str:
        return self.label or resolve_spec(self.source, scale=self.scale).name


def expand(args: list[str] | tuple[str, ...], scale: float | None = None,
           physical: Physical = NO_PHYSICAL) -> list[ObjectRef]:
    """The objects the arguments name; ``scale`` and ``physical`` apply to
    each, except where a manifest line gives its own."""
    refs: list[ObjectRef] = []
    for arg in args:
        refs += _expand_one(arg, scale, physical)
    return _unique_labels(refs)


def _expand_one(arg: str, scale: float | None, physical: Physical) -> list[ObjectRef]:
    if arg.startswith("@"):
        return _manifest(Path(arg[1:]), scale, physical)
    return [replace(ref, physical=physical) for ref in _expand_plain(arg, scale)]


def _expand_plain(arg: str, scale: float | None) -> list[ObjectRef]:
    if arg == "builtin:all":
        return [ObjectRef(name, scale) for name in builtin_specs()]
    if arg == "builtin:random" or arg.startswith("builtin:random:"):
        return [ObjectRef(f"{RANDOM_PREFIX}{i:03d}", scale) for i in _random_range(arg)]
    if arg.startswith("builtin:"):  # one by name (random_NNN too), even where a folder of that name is in the way
        if not is_registered(arg[len("builtin:"):]):
            raise InputError(f"'{arg}': no built-in object of that name (see `grasp objects`)")
        return [ObjectRef(arg[len("builtin:"):], scale)]
    path = Path(arg).expanduser()
    if path.is_dir():
        files = _objects(p for p in path.rglob("*") if p.suffix.lower() in OBJECT_SUFFIXES and p.is_file()
                         and not _hidden(p.relative_to(path)))
        if not files:
            also = f"; for the built-in object of that name write builtin:{arg}" if is_registered(arg) else ""
            raise InputError(f"{path}: folder holds no mesh or URDF files ({', '.join(OBJECT_SUFFIXES)}){also}")
        return [ObjectRef(str(_absolute(str(p))), scale) for p in files]
    if any(c in arg for c in "*?["):
        files = _objects(Path(p) for p in glob.glob(str(path), recursive=True)
                         if Path(p).suffix.lower() in OBJECT_SUFFIXES)
        if not files:
            raise InputError(f"'{arg}': no mesh or URDF files match")
        return [ObjectRef(str(_absolute(str(p))), scale) for p in files]
    return [ObjectRef(arg, scale)]


def _objects(files: Iterable[Path]) -> list[Path]:
    """The objects among a folder's or a glob's ``files``, sorted: each URDF, and each mesh file no URDF of them
    names (a URDF's meshes are its object's parts, planned as it places them)."""
    files = sorted(files)
    parts = {m for p in files if p.suffix.lower() == URDF_SUFFIX for m in named_meshes(p)}
    return [p for p in files if p.suffix.lower() == URDF_SUFFIX or p.resolve() not in parts]


#: Folders a folder's walk skips besides hidden ones: the resource forks a zip made on macOS holds.
SKIPPED_FOLDERS = ("__MACOSX",)


def _hidden(relative: Path) -> bool:
    """Whether a folder's walk skips the file at ``relative`` to it: a hidden file or one in a hidden folder
    (``.git/``, macOS's ``._mug.obj`` resource forks), or in ``__MACOSX/``: as a glob's ``*`` skips them."""
    return any(part.startswith(".") or part in SKIPPED_FOLDERS for part in relative.parts)


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
    if "-" not in spec and not 1 <= result.stop <= RANDOM_COUNT:
        why = "names no objects" if result.stop < 1 else f"is more than the {RANDOM_COUNT} random objects"
        raise InputError(f"'{arg}': a count of {result.stop} {why}; give a count of 1 to {RANDOM_COUNT}")
    if not result:
        raise InputError(f"'{arg}': the first, {lo}, comes after the last, {hi}; write builtin:random:{hi}-{lo}")
    if result.start < 0 or result.stop > RANDOM_COUNT:
        raise InputError(f"'{arg}': range must lie within 0-{RANDOM_COUNT - 1}")
    return result


def _manifest(path: Path, scale: float | None, physical: Physical) -> list[ObjectRef]:
    if not path.is_file():
        raise InputError(f"{path}: manifest not found")
    refs = []
    for number, raw in enumerate(_manifest_text(path).splitlines(), start=1):
        where = f"{path}:{number}"
        tokens = _tokens(raw, where)
        if tokens:
            refs.append(replace(_manifest_line(tokens, where, path.parent, scale, physical),
                                manifest=str(_absolute(str(path)))))
    if not refs:
        raise InputError(f"{path}: manifest lists no objects")
    return refs


def _manifest_text(path: Path) -> str:
    """A manifest's text (:func:`~planner.specs.toml.decode_text`: a UTF-16 one, Windows PowerShell's ``>``'s,
    was an internal error; a byte-order mark is no part of the first object's name)."""
    return decode_text(path.read_bytes(), path, "the manifest", InputError)


def _tokens(raw: str, where: str) -> list[str]:
    """A manifest line's fields: split at blanks, a path with blanks or ``#``
    in double quotes; ``#`` outside them starts a comment; apostrophes and
    backslashes are kept as they are (``bob's mug.obj`` in quotes, a Windows
    path)."""
    lex = shlex.shlex(raw, posix=True)
    lex.whitespace_split, lex.commenters, lex.escape, lex.quotes = True, "#", "", '"'

    try:
        return list(lex)
    except ValueError as exc:  # an unclosed quote
        raise InputError(f"{where}: {exc} in '{raw.strip()}' (a path with blanks or # goes in double quotes)") \
            from None


def _manifest_line(tokens: list[str], where: str, folder: Path, scale: float | None, physical: Physical
                   ) -> ObjectRef:
    """One manifest line's fields (see :data:`MANIFEST_LINE`); ``where``: file:line for errors."""
    source, *rest = tokens
    line = shlex.join(tokens)
    if not source:
        raise InputError(f"{where}: expected '{MANIFEST_LINE}', got '{line}' (an empty object)")
    columns: dict[str, str] = {}
    for i, token in enumerate(rest):
        key, sep, value = token.partition("=")
        if not sep and i == 0:
            key, value = "scale", token
        elif not sep or key not in ("scale", *PHYSICAL_KEYS) or key in columns:
            why = (f"a value without a name, '{token}', after '{rest[i - 1]}' (only the scale, right after the "
                   "object, goes without one: give KEY=VALUE)" if not sep else f"{key} given twice"
                   if key in columns else f"unknown column '{key}' (columns: {', '.join(('scale', *PHYSICAL_KEYS))})")
            raise InputError(f"{where}: {why}; expected '{MANIFEST_LINE}'")
        columns[key] = value
    item_scale, row_scale = scale, "scale" in columns
    if row_scale:
        text = columns.pop("scale")
        try:
            item_scale = float(text)
        except ValueError:
            raise InputError(f"{where}: scale '{text}' is not a number (a path with blanks goes in double quotes: "
                             f"\"{source.removesuffix(chr(92))} {text}\"; a backslash is kept as it is)") from None
        if not (math.isfinite(item_scale) and item_scale > 0):
            raise InputError(f"{where}: scale must be a positive number, got {item_scale:g}")
    target = _absolute(str(folder / Path(source).expanduser()))  # an absolute path stays itself
    if not is_registered(source) and (target.is_dir() or (any(c in source for c in "*?[") and not target.is_file())):
        raise InputError(f"{where}: {source} is a {'folder' if target.is_dir() else 'glob'}: a manifest's line names "
                         f"one object; give it on the command line (`grasp generate {shlex.quote(str(target))}`), "
                         "or list its files")
    suffix = Path(source).suffix.lower()
    given = Physical.checked(columns, where).over(physical)
    if suffix in OBJECT_SUFFIXES:
        if not Path(source).is_absolute():
            source = str(_absolute(str(folder / source)))
        if not Path(source).is_file():
            windows = " (a Windows path? write / between folders)" if "\\" in tokens[0] else ""
            raise InputError(f"{where}: {source}: file not found{windows}")
    elif suffix and not is_registered(source):
        raise InputError(f"{where}: {source}: unsupported mesh type '{suffix}'; use one of "
                         f"{', '.join(MESH_SUFFIXES)}, or a URDF ({URDF_SUFFIX})")
    if suffix not in MESH_SUFFIXES:  # a name, the scale a primitive refuses, a URDF: checked where the line is known
        try:
            resolve_spec(source, scale=item_scale, scale_from="the row's scale" if row_scale else "--scale",
                         **given.given())
        except InputError as exc:
            raise InputError(f"{where}: {exc}") from None
    return ObjectRef(source, item_scale, physical=given)


def _unique_labels(refs: list[ObjectRef]) -> list[ObjectRef]:
    """Drop repeats; give mesh files sharing a stem distinct names: their
    parent folders prefixed until the names differ, and the file's suffix
    kept where only it differs (``part.obj``, ``part.stl``). A file whose
    stem no other file of the run shares keeps its stem alone."""
    seen: dict[tuple[str, float | None, Physical], ObjectRef] = {}
    for ref in refs:
        seen.setdefault((ref.source, ref.scale, ref.physical), ref)
    refs = list(seen.values())
    files = {r.source: _absolute(r.source) for r in refs if Path(r.source).suffix.lower() in OBJECT_SUFFIXES}
    by_stem: dict[str, list[Path]] = {}
    for path in sorted(set(files.values())):  # one file given two ways (./m/a.obj, m/a.obj) is one path
        by_stem.setdefault(path.stem, []).append(path)
    labels = {p: label for group in by_stem.values() for p, label in _apart(group).items()}
    if len(set(labels.values())) < len(labels):  # a prefixed name met another file's (part.obj.stl): all at once
        labels = _apart(list(labels))
    if all(label == p.stem for p, label in labels.items()):
        return refs
    return [replace(r, label=labels[files[r.source]]) if r.source in files else r for r in refs]


def _apart(paths: list[Path]) -> dict[Path, str]:
    """Distinct labels of ``paths``: the fewest parent folders prefixed, then the suffix kept too; the whole
    paths where neither tells them apart (the same folders and name under two roots: two Windows drives)."""
    deepest = max((len(_folders(p)) for p in paths), default=0)
    for suffix in (False, True):
        for depth in range(deepest + 1):
            labels = {p: _label(p, depth, suffix) for p in paths}
            if len(set(labels.values())) == len(labels):
                return labels
    return {p: str(p) for p in paths}


def _absolute(source: str) -> Path:
    """``source`` as an absolute path, ``..`` and ``.`` folded, symlinks kept (a link is its own file, as a copy
    is: its name and its sidecar)."""
    return Path(os.path.abspath(Path(source).expanduser()))


def _folders(path: Path) -> tuple[str, ...]:
    """The folders of ``path`` that may prefix its name (not the root)."""
    return tuple(p for p in path.parent.parts if p != path.anchor)


def _label(path: Path, depth: int, suffix: bool = False) -> str:
    """``path``'s stem (its name with ``suffix``), after its last ``depth`` folders."""
    folders = _folders(path)
    return "/".join([*folders[len(folders) - min(depth, len(folders)):], path.name if suffix else path.stem])


#: Seeds are stored as SQLite integers and seed numpy's generators, which take no negative ones.
MAX_SEED = 2**63 - 1


def check_seed(seed: int) -> int:
    """``seed``, or a one-line error before anything runs (a negative one failed every unit, stored as failed;
    one beyond SQLite's integers was an internal error)."""
    if not 0 <= seed <= MAX_SEED:
        raise InputError(f"--seed must be an integer from 0 to {MAX_SEED}, got {seed}")
    return seed


def check_output(path: Path, option: str, *, folder: bool = False) -> Path:
    """``path``, or a one-line error before any work where it cannot be written: a file's path that is a folder,
    a folder's that is a file, a folder above it that is a file or not writable. Nothing is created (a command
    refused later leaves nothing behind); a write that fails all the same is caught by :func:`writing`."""
    path = Path(path)
    if folder and path.exists() and not path.is_dir():
        raise InputError(f"{path}: {option} must be a folder, but it is a file")
    if not folder and path.is_dir():
        raise InputError(f"{path}: {option} is a folder; give a file path")
    above = path if folder else path.parent
    while not above.exists() and above != above.parent:
        above = above.parent
    if not above.is_dir():
        raise InputError(f"{path}: {option} cannot be written: {above} is a file, not a folder")
    if not os.access(above, os.W_OK | os.X_OK):
        raise InputError(f"{path}: {option} cannot be written: {above} is not writable")
    return path


@contextmanager
def writing(path: Path, option: str) -> Iterator[None]:
    """A write to ``path`` whose OSError (a read-only or full disk, a path the system refuses) is one line."""
    try:
        yield
    except OSError as exc:
        raise InputError(f"{path}: {option} cannot be written ({exc.strerror or exc})") from exc
