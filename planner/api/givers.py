"""Who gives an object's mass (or density), friction and up, first first: the run (flags, a manifest's
columns), then its files (a sidecar, a URDF's own; :func:`~planner.specs.objects.file_values`); and saying so
where one replaces another's value (:func:`note_overridden`) or where a stored object's values came from a
file (:func:`from_files`)."""

from __future__ import annotations

from planner import prepare
from planner.specs.objects import URDF_FILE, ObjectSpec, file_values
from planner.specs.physical import Physical


def _givers(named: str, spec: ObjectSpec, given: Physical) -> dict[str, list[tuple[str, dict[str, float | str]]]]:
    """For the mass (or density), the friction and the up of the object ``named``: who gives it, first first, each as
    (its file's name, '' for the run's ``given`` values: flags, a manifest's columns; its values of that property):
    the run, the sidecar, a URDF's own (:func:`~planner.specs.objects.file_values`)."""
    layers = [("", given.given()), *file_values(named, spec)]
    props = {"mass": ("mass", "density"), "friction": ("friction",), "up": ("up",)}
    return {prop: [(who, part) for who, values in layers if (part := {k: v for k, v in values.items() if k in keys})]
            for prop, keys in props.items()}


def from_files(named: str, spec: ObjectSpec, given: Physical) -> str:
    """`` (mass from banana.toml)`` where a file of the object ``named`` (its sidecar, a URDF) gave what the run
    did not."""
    used: dict[str, list[str]] = {}
    for prop, givers in _givers(named, spec, given).items():
        if givers and givers[0][0]:
            used.setdefault(givers[0][0], []).append(prop)
    said = [" and ".join(props) + f" from {who}" for who, props in used.items()]
    return f" ({', '.join(said)})" if said else ""


def note_overridden(named: str, spec: ObjectSpec, given: Physical) -> None:
    """Say (a line on stderr) where the run's values (flags, a manifest's columns) replace its files' (a sidecar's,
    a URDF's), and where a sidecar's replace a URDF's."""
    if not given.given() and spec.kind != URDF_FILE:  # nothing replaces anything: no sidecar read again
        return
    pairs: dict[tuple[str, str], tuple[dict[str, float | str], dict[str, float | str]]] = {}
    for givers in _givers(named, spec, given).values():
        if len(givers) > 1 and givers[0][1] != givers[1][1]:  # the same value given twice replaces nothing
            (winner, ours), (loser, theirs) = givers[:2]
            both = pairs.setdefault((winner, loser), ({}, {}))
            both[0].update(ours)
            both[1].update(theirs)
    for (winner, loser), (ours, theirs) in pairs.items():
        verb = "replaces" if len(ours) == 1 else "replace"
        prepare.noted(f"object '{spec.name}'", f"{_listed(ours)} {f'from {winner}' if winner else 'as given'} "
                      f"{verb} {loser}'s {_listed(theirs)}")


def _listed(values: dict[str, float | str]) -> str:
    return ", ".join(f"{k} {v}" if isinstance(v, str) else f"{k} {v:g}" for k, v in values.items())
