"""Preshape taxonomies: ``preshapes/<hand>.toml``.

A preshape is a named open hand posture with taxonomy tags (power /
precision / intermediate and a class from a published taxonomy), an optional
closing synergy overriding the hand's, and the standoffs that suit it. A
*table* preshape (``table = true``) is for objects resting on a table only:
the sweep on the table and planning on the spot try it, the sweep of the
object alone does not (:func:`sweep_preshapes`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from planner import assets
from planner.errors import ConfigError, UnknownNameError
from planner.specs.hands import HandSpec, roll_symmetry
from planner.specs.toml import Fields, read_toml

TAGS = ("power", "precision", "intermediate")


@dataclass(frozen=True)
class Preshape:
    """Open joint values [rad or m] of the driven joints, and how to close."""

    name: str
    tags: tuple[str, ...]
    taxonomy: str
    joints: dict[str, float]  # every finger joint (mimics filled in)
    close: dict[str, float]  # synergy: closing rate per driven joint
    standoffs: tuple[float, ...]  # [m]
    tcp: np.ndarray  # (3,) [m] hand frame: where the approach ray passes (default: the hand's)
    table: bool = False  # only for an object on a table (sweep_preshapes)
    roll_symmetry: int = 1  # its grasp repeats after 2 pi / (the hand's x this) about the approach: rolls spread
    #                         over that turn (a pinch along one axis: 2, so that 2 rolls pinch along 2 axes)


#: Parsed taxonomies by (file, its mtime and size, the hand object): a shake
#: trial asks for its grasp's preshape twice, and parsing the TOML each time
#: cost more than a Barrett trial's set-up (1.5 ms per call).
_PARSED: dict[tuple, tuple[HandSpec, tuple[Preshape, ...]]] = {}


def load_preshapes(hand: HandSpec, names: list[str] | None = None) -> tuple[Preshape, ...]:
    """The hand's preshapes, all or the ``names`` asked for (in that order)."""
    path = assets.project_dir("preshapes") / f"{hand.name}.toml"
    stat = path.stat() if path.is_file() else None
    key = (str(path), stat and (stat.st_mtime_ns, stat.st_size), id(hand))
    cached = _PARSED.get(key)
    if cached is None or cached[0] is not hand:
        cached = _PARSED[key] = (hand, _parse(hand, path))
    shapes = cached[1]
    if not names:
        return shapes
    by_name = {s.name: s for s in shapes}
    for name in names:
        if name not in by_name:
            raise UnknownNameError("preshape", name, by_name)
    return tuple(by_name[n] for n in names)


def sweep_preshapes(hand: HandSpec, names: list[str] | None = None, on_table: bool = False
                    ) -> tuple[Preshape, ...]:
    """The preshapes a sweep tries: the ``names`` asked for, else all of the
    hand's but its table preshapes when the object is not ``on_table``."""
    shapes = load_preshapes(hand, names)
    return shapes if names or on_table else tuple(s for s in shapes if not s.table)


def _parse(hand: HandSpec, path: Path) -> tuple[Preshape, ...]:
    f = Fields(read_toml(path), str(path))
    if f.get("hand", hand.name) != hand.name:
        raise ConfigError(f"{path} field 'hand': says '{f.data['hand']}', expected '{hand.name}'")
    shapes = [_preshape(hand, item) for item in f.tables("preshape")]
    f.check_unknown()
    by_name = {s.name: s for s in shapes}
    if len(by_name) != len(shapes):
        raise ConfigError(f"{path}: two preshapes share a name")
    return tuple(shapes)


def _preshape(hand: HandSpec, f: Fields) -> Preshape:
    tags = tuple(f.strs("tags"))
    for tag in tags:
        if tag not in TAGS:
            raise ConfigError(f"{f.where} field 'tags': unknown tag '{tag}'; use {', '.join(TAGS)}")
    driven = {j.name: j for j in hand.driven}
    values = f.table("joints")
    for name in values.names():
        if name not in driven:
            raise ConfigError(f"{values.where}: '{name}' is not a driven joint of hand '{hand.name}'; "
                              f"driven joints: {', '.join(driven)}")
        joint = driven[name]
        v = values.float(name)
        if not joint.lower - 1e-9 <= v <= joint.upper + 1e-9:
            raise ConfigError(f"{values.where}: {name} = {v} is outside its limits [{joint.lower}, {joint.upper}]")
    open_driven = {name: values.float(name) if values.has(name) else j.lower for name, j in driven.items()}
    close = {j.name: j.close for j in hand.driven}
    if f.has("close"):
        override = f.table("close")
        for name in override.names():
            if name not in driven:
                raise ConfigError(f"{override.where}: '{name}' is not a driven joint of hand '{hand.name}'")
            close[name] = override.float(name)
    if not any(close.values()):
        raise ConfigError(f"{f.where}: the closing synergy moves no joint")
    standoffs = tuple(f.floats("standoffs", default=[0.0]))
    if any(s < 0 for s in standoffs) or not standoffs:
        raise ConfigError(f"{f.where} field 'standoffs': needs non-negative distances [m]")
    tcp = np.array(f.floats("tcp", 3)) if f.has("tcp") else hand.tcp
    table = f.bool("table", False)
    return Preshape(name=f.str("name"), tags=tags, taxonomy=f.get("taxonomy", ""),
                    joints=hand.full_configuration(open_driven), close=close, standoffs=standoffs, tcp=tcp,
                    table=table, roll_symmetry=roll_symmetry(f))
