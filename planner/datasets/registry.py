"""The file formats, registered side by side (as trimesh's ``exchange/``
keeps each format's loader and exporter together): each format module ends
with one :func:`register` call naming its writer and, if it has one, its
reader; the exporter and the importer find formats here and nowhere else
(through :mod:`planner.datasets.formats`, which imports every format module).

A registration is checked when it is made: a hook that is missing, not
callable or takes other arguments than its kind's, a name taken twice or a
format with neither writer nor reader raises at import time (a
:class:`RegistrationError`), so a misspelled hook cannot be skipped unseen.

Kinds of writers:

- :class:`PairWriter`: one file per (object, hand) at ``relative_path(stem,
  hand)`` below the export folder, written by ``write(path, object, hand,
  batches)`` (returns the grasps written); ``finish(out_dir, hands)`` once
  after every pair (optional); ``mesh_copies``: where else below the export
  folder each object's mesh goes (``{stem}`` in the path);
- :class:`TableWriter`: one file ``file`` of every grasp, written by
  ``write(path, streams)``; ``notes(pairs)`` (optional): what a reader of
  that file should know about the exported (object, hand) pairs, printed
  and kept in the manifest with the export's other notes.

A :class:`Reader` reads one grasp file back for ``grasp import``:
``header(path)``, ``poses(path, hand)``, ``grasps(path, hand, object,
poses)`` and ``simulation(path)`` (see :mod:`planner.datasets.acronym`);
``openings(path, hand)`` (optional): the :class:`Openings` each pose was
planned with, where the file gives them (``--rescore`` closes from them).
"""

from __future__ import annotations

import inspect
import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from planner.errors import PlannerError, UnknownNameError

if TYPE_CHECKING:
    from planner.specs.hands import HandSpec

#: A format's name: what ``--format`` takes.
NAME = re.compile(r"[a-z][a-z0-9_]*")


class RegistrationError(PlannerError):
    """A format module registered something unusable (a programming error)."""


def _check_hooks(kind: object, arguments: dict[str, int], optional: tuple[str, ...] = ()) -> None:
    """Every hook of ``kind`` (a writer or reader) is callable with its number
    of positional arguments."""
    for name, count in arguments.items():
        hook = getattr(kind, name)
        if hook is None and name in optional:
            continue
        if not callable(hook):
            raise RegistrationError(f"{type(kind).__name__}.{name} must be a function, got {hook!r}")
        try:
            inspect.signature(hook).bind(*range(count))
        except TypeError:
            raise RegistrationError(f"{type(kind).__name__}.{name} must take {count} positional arguments: "
                                    f"{getattr(hook, '__qualname__', hook)}{inspect.signature(hook)}") from None


@dataclass(frozen=True)
class PairWriter:
    """One file per (object, hand); see the module docstring."""

    relative_path: Callable
    write: Callable
    finish: Callable | None = None
    mesh_copies: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        _check_hooks(self, {"relative_path": 2, "write": 4, "finish": 2}, optional=("finish",))
        for copy in self.mesh_copies:
            if not isinstance(copy, str) or "{stem}" not in copy:
                raise RegistrationError(f"PairWriter.mesh_copies: {copy!r} must be a path with '{{stem}}' in it")


@dataclass(frozen=True)
class TableWriter:
    """One file of every grasp; see the module docstring."""

    file: str
    write: Callable
    notes: Callable | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.file, str) or not self.file or "/" in self.file:
            raise RegistrationError(f"TableWriter.file: {self.file!r} must be a file name")
        _check_hooks(self, {"write": 2, "notes": 1}, optional=("notes",))


@dataclass(frozen=True)
class Reader:
    """Reads one grasp file back; see the module docstring."""

    header: Callable
    poses: Callable
    grasps: Callable
    simulation: Callable
    openings: Callable | None = None
    labels: Callable | None = None  # path -> the (N,) FileLabel or None per pose a foreign file gives

    def __post_init__(self) -> None:
        _check_hooks(self, {"header": 1, "poses": 2, "grasps": 4, "simulation": 1, "openings": 2, "labels": 1},
                     optional=("openings", "labels"))


@dataclass(frozen=True)
class Openings:
    """The open hand each of a file's N poses was planned with, as far as the file gives it.

    ``joints`` (N, D) [rad or m]: the hand's driven joints (:attr:`HandSpec.driven` order), NaN where not given;
    ``preshapes`` (N,): each pose's preshape name ('' where not given)."""

    joints: np.ndarray
    preshapes: tuple[str, ...]

    def __post_init__(self) -> None:
        if self.joints.ndim != 2 or len(self.joints) != len(self.preshapes):
            raise ValueError(f"Openings: joints {self.joints.shape} for {len(self.preshapes)} preshapes")

    def rows(self, first: int, stop: int) -> Openings:
        return Openings(self.joints[first:stop], self.preshapes[first:stop])

    def take(self, rows: np.ndarray) -> Openings:
        """The openings of ``rows`` (k,) int, in that order (a sample of a file's poses)."""
        return Openings(self.joints[rows], tuple(self.preshapes[int(i)] for i in rows))

    def at(self, hand: HandSpec, row: int) -> tuple[str, dict[str, float]] | None:
        """Row ``row``'s preshape name and every finger joint [rad or m] of ``hand`` open as it gives them
        (mimics follow); None unless the row gives every driven joint within its limits."""
        driven = self.joints[row].tolist()
        if len(driven) != len(hand.driven) or not all(j.lower <= v <= j.upper for j, v in zip(hand.driven, driven)):
            return None  # NaN: not given
        return self.preshapes[row], hand.full_configuration({j.name: v for j, v in zip(hand.driven, driven)})


@dataclass(frozen=True)
class Format:
    """A registered format: its writer, its reader (either may be None, not both)."""

    name: str
    writer: PairWriter | TableWriter | None
    reader: Reader | None


_FORMATS: dict[str, Format] = {}


def register(name: str, writer: PairWriter | TableWriter | None = None, reader: Reader | None = None) -> Format:
    """Register format ``name`` (called once, at the end of its module)."""
    if not isinstance(name, str) or not NAME.fullmatch(name):
        raise RegistrationError(f"format name {name!r} must be lower case letters, digits and '_'")
    if name in _FORMATS:
        raise RegistrationError(f"format '{name}' is registered twice")
    if writer is None and reader is None:
        raise RegistrationError(f"format '{name}' registers neither a writer nor a reader")
    if writer is not None and not isinstance(writer, (PairWriter, TableWriter)):
        raise RegistrationError(f"format '{name}': writer must be a PairWriter or TableWriter, got {writer!r}")
    if reader is not None and not isinstance(reader, Reader):
        raise RegistrationError(f"format '{name}': reader must be a Reader, got {reader!r}")
    found = _FORMATS[name] = Format(name, writer, reader)
    return found


def export_formats() -> tuple[str, ...]:
    """Names of the formats with a writer, sorted."""
    return tuple(sorted(n for n, f in _FORMATS.items() if f.writer is not None))


def import_formats() -> tuple[str, ...]:
    """Names of the formats with a reader, sorted."""
    return tuple(sorted(n for n, f in _FORMATS.items() if f.reader is not None))


def writer(name: str) -> PairWriter | TableWriter:
    """The writer of format ``name``; an unknown name lists the valid ones."""
    found = _FORMATS.get(name)
    if found is None or found.writer is None:
        raise UnknownNameError("format", name, export_formats())
    return found.writer


def reader(name: str) -> Reader:
    """The reader of format ``name``; an unknown name lists the valid ones."""
    found = _FORMATS.get(name)
    if found is None or found.reader is None:
        raise UnknownNameError("import format", name, import_formats())
    return found.reader

