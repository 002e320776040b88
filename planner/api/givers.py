"""Who gives an object's mass (or density), friction, up and centre of mass, first first: the run (flags, a manifest's
columns), then its files (a sidecar, a URDF's own; :func:`~planner.specs.objects.file_values`); and saying so
where one replaces another's value (:func:`note_overridden`) or where a stored object's values came from a
file (:func:`from_files`)."""

from __future__ import annotations

from planner import prepare
from planner.record.field import same_com
from planner.specs.objects import URDF_FILE, ObjectSpec, file_values
from planner.specs.physical import Physical, Value


def _givers(named: str, spec: ObjectSpec, given: Physical) -> dict[str, list[tuple[str, dict[str, Value]]]]:
    """For the mass (or density), the friction, the up and the centre of mass of the object ``named``: who gives
    it, first first, each as (its file's name, '' for the run's ``given`` values: flags, a manifest's columns; its
    values of that property): the run, the sidecar, a URDF's own (:func:`~planner.specs.objects.file_values`)."""
    layers = [("", given.given()), *file_values(named, spec)]
    props = {"mass": ("mass", "density"), "friction": ("friction",), "up": ("up",), "com": ("com",)}
    return {prop: [(who, part) for who, values in layers if (part := {k: v for k, v in values.items() if k in keys})]
            for prop, keys in props.items()}


def from_files(named: str, spec: ObjectSpec, given: Physical) -> str:
    """`` (mass from banana.toml)`` where a file of the object ``named`` (its sidecar, a URDF) gave what the run
    did not."""
    used: dict[str, list[str]] = {}
    for prop, givers in _givers(named, spec, given).items():
        if givers and givers[0][0]:
            used.setdefault(givers[0][0], []).append(prop)
    said = [f"{_joined(props)} from {who}" for who, props in used.items()]
    return f" ({', '.join(said)})" if said else ""


def note_overridden(named: str, spec: ObjectSpec, given: Physical) -> None:
    """Say (a line on stderr) where the run's values (flags, a manifest's columns) replace its files' (a sidecar's,
    a URDF's), and where a sidecar's replace a URDF's."""
    if not given.given() and spec.kind != URDF_FILE:  # nothing replaces anything: no sidecar read again
        return
    pairs: dict[tuple[str, str], tuple[dict[str, Value], dict[str, Value]]] = {}
    for givers in _givers(named, spec, given).values():
        if len(givers) > 1 and not _same(givers[0][1], givers[1][1]):  # the same value given twice replaces nothing
            (winner, ours), (loser, theirs) = givers[:2]
            both = pairs.setdefault((winner, loser), ({}, {}))
            both[0].update(ours)
            both[1].update(theirs)
    for (winner, loser), (ours, theirs) in pairs.items():
        verb = "replaces" if len(ours) == 1 else "replace"
        prepare.noted(f"object '{spec.name}'", f"{_listed(ours)} {f'from {winner}' if winner else 'as given'} "
                      f"{verb} {loser}'s {_listed(theirs)}")


def _same(ours: dict[str, Value], theirs: dict[str, Value]) -> bool:
    """Whether two givers' values of one property are the same: a centre of mass to what the store keeps (a URDF's
    own is scaled by the run's --scale, 0.1 * 3 is not 0.3), the others exactly."""
    if ours.keys() != theirs.keys():
        return False
    return all(same_com(v, theirs[k]) if k == "com" else v == theirs[k] for k, v in ours.items())


def _joined(words: list[str]) -> str:
    """``a``, ``a and b``, ``a, b and c``."""
    return words[0] if len(words) == 1 else f"{', '.join(words[:-1])} and {words[-1]}"


def _listed(values: dict[str, Value]) -> str:
    return ", ".join(f"{k} {_shown(v)}" for k, v in values.items())


def _shown(value: Value) -> str:
    """An axis as it is, a number or a point [m] in short."""
    if isinstance(value, str):
        return value
    return f"[{', '.join(f'{v:g}' for v in value)}]" if isinstance(value, tuple) else f"{value:g}"
