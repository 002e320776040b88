"""An object's physical properties as a user gives them: a mass [kg] or a
uniform density [kg/m^3] (one property given two ways: never both), a
Coulomb friction coefficient, the axis of the file's frame that is up as the
object stands (:mod:`planner.specs.up`), its centre of mass [m] and, for a URDF
file, which of its elements it is made of (``collision`` or ``visual``), each
checked with an error naming where it was given and the field.
:mod:`planner.specs.objects` says which source wins.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from planner.errors import InputError
from planner.specs.up import up_axis

#: Largest Coulomb friction coefficient accepted: rubber on rough surfaces
#: reaches about 1-2, so a larger value is a typo (a percentage, a unit mix-up).
MAX_FRICTION = 3.0
#: The keys of a physical-properties sidecar (``banana.toml`` beside ``banana.obj``) and a manifest's columns.
PHYSICAL_KEYS = ("mass", "density", "friction", "up", "com", "geometry")
#: The elements of a URDF file an object may be made of, the first preferred: the collision shape is the one PyBullet
#: simulates; a file without one is planned on its visual shape.
GEOMETRIES = ("collision", "visual")
#: A point [m] (a centre of mass): x, y, z.
Vector = tuple[float, float, float]
#: A property's value: a number, an axis or a geometry, a point.
Value = float | str | Vector
_UNITS = {"mass": "kg", "density": "kg/m^3", "friction": "Coulomb coefficient"}
#: [kg/m^3] from a foam (expanded polystyrene ~10) to osmium (22,590): an object's mass over its volume outside
#: these is noted (a 5 mm bead at the default 0.2 kg: 3e6; a mesh scaled x10 at the default: ~1).
PLAUSIBLE_DENSITY = (5.0, 23_000.0)


@dataclass(frozen=True)
class Physical:
    """Physical properties a user gives for an object; None: not given.

    ``mass`` [kg] or ``density`` [kg/m^3] (uniform over the closed mesh; the
    mass is then density x volume), never both; ``friction``: Coulomb
    coefficient, 0 < mu <= :data:`MAX_FRICTION`; ``up``: the axis of the
    object frame that is up as it stands (:data:`planner.specs.up.AXES`);
    ``com``: (x, y, z) [m] the centre of mass in the object frame (the scaled
    file's); ``geometry``: a URDF file's elements, one of :data:`GEOMETRIES`.
    Build with :meth:`checked` from user input for an error naming the source and field.
    """

    mass: float | None = None
    density: float | None = None
    friction: float | None = None
    up: str | None = None
    com: Vector | None = None
    geometry: str | None = None

    def __post_init__(self) -> None:
        check_physical(self.mass, self.density, self.friction, "", "")
        if self.up is not None:
            object.__setattr__(self, "up", up_axis(self.up))
        if self.com is not None:
            object.__setattr__(self, "com", _vector(self.com, "com", "", ""))
        if self.geometry is not None:
            object.__setattr__(self, "geometry", _geometry(self.geometry, "", ""))

    @classmethod
    def checked(cls, values: Mapping[str, object], where: str = "", prefix: str = "") -> Physical:
        """From raw values (numbers, or text of numbers); the error names
        ``where`` (a file and line) and the field as ``prefix + key``."""
        unknown = sorted(set(values) - set(PHYSICAL_KEYS))
        if unknown:
            raise InputError(f"{_at(where)}unknown field '{prefix}{unknown[0]}'; use "
                             f"{', '.join(prefix + k for k in PHYSICAL_KEYS)}")
        numbers = {k: _number(values[k], k, where, prefix) for k in PHYSICAL_KEYS[:3] if values.get(k) is not None}
        check_physical(numbers.get("mass"), numbers.get("density"), numbers.get("friction"), where, prefix)
        up = None if values.get("up") is None else up_axis(values["up"], where, f"{prefix}up")
        com = None if values.get("com") is None else _vector(values["com"], "com", where, prefix)
        geometry = None if values.get("geometry") is None else _geometry(values["geometry"], where, prefix)
        return cls(**numbers, up=up, com=com, geometry=geometry)

    def over(self, base: Physical) -> Physical:
        """These properties, with ``base``'s where these give none (mass or
        density together: whichever gives either decides)."""
        heavy = self.mass is not None or self.density is not None
        return Physical(self.mass if heavy else base.mass, self.density if heavy else base.density,
                        *(getattr(self, k) if getattr(self, k) is not None else getattr(base, k)
                          for k in PHYSICAL_KEYS[2:]))

    def given(self) -> dict[str, Value]:
        return {k: v for k in PHYSICAL_KEYS if (v := getattr(self, k)) is not None}


def _at(where: str) -> str:
    return f"{where}: " if where else ""


def _number(value: object, key: str, where: str, prefix: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise InputError(f"{_at(where)}{prefix}{key} must be a number [{_UNITS[key]}], got {value!r}")
    try:
        return float(value)
    except ValueError:
        raise InputError(f"{_at(where)}{prefix}{key} must be a number [{_UNITS[key]}], got '{value}'") from None


def _vector(value: object, key: str, where: str, prefix: str) -> Vector:
    """Three finite numbers [m]: a list (a sidecar's ``[x, y, z]``) or text ``x,y,z`` (a manifest column)."""
    items = value.split(",") if isinstance(value, str) else value
    try:
        if isinstance(items, (list, tuple)) and len(items) == 3 and not any(isinstance(v, bool) for v in items):
            x, y, z = (float(v) for v in items)
            if all(math.isfinite(v) for v in (x, y, z)):
                return (x, y, z)
    except (TypeError, ValueError):
        pass
    shown = f"'{value}'" if isinstance(value, str) else repr(value)
    raise InputError(f"{_at(where)}{prefix}{key} must be three numbers [m], x, y, z in the object frame "
                     f"(a sidecar's [0.01, 0, 0.02], a manifest's 0.01,0,0.02), got {shown}")


def _geometry(value: object, where: str, prefix: str) -> str:
    if value not in GEOMETRIES:
        raise InputError(f"{_at(where)}{prefix}geometry must be {' or '.join(GEOMETRIES)} (the URDF elements the "
                         f"object is made of), got {value!r}")
    return str(value)


def check_physical(mass: float | None, density: float | None, friction: float | None, where: str = "",
                   prefix: str = "") -> None:
    """Raise an InputError naming the field of the first bad value."""
    if mass is not None and density is not None:
        raise InputError(f"{_at(where)}{prefix}mass and {prefix}density exclude each other (the mass is density x "
                         "volume); give one")
    for key, value in (("mass", mass), ("density", density), ("friction", friction)):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise InputError(f"{_at(where)}{prefix}{key} must be a positive number [{_UNITS[key]}], got {value}")
    if friction is not None and friction > MAX_FRICTION:
        raise InputError(f"{_at(where)}{prefix}friction must lie in (0, {MAX_FRICTION:g}] (a Coulomb coefficient), "
                         f"got {friction}")


def density_note(name: str, mass: float, density: float) -> str | None:
    """The line that says an object's mass [kg] over its volume, ``density`` [kg/m^3], is no solid's (None: it is
    plausible, :data:`PLAUSIBLE_DENSITY`), and where to give its mass or its scale."""
    from planner.specs.objects import DEFAULT_MASS  # which imports this module

    low, high = PLAUSIBLE_DENSITY
    if low <= density <= high:
        return None
    scale = "; if its mesh is not in metres (a model scaled to 1 unit across), --scale" if density < low else ""
    return (f"note: {name} weighs {mass:.3g} kg in its volume: {density:.3g} kg/m^3, outside any solid's {low:g}-"
            f"{high:,.0f} (the default is {DEFAULT_MASS:g} kg); if that is not its weight, give --mass or --density "
            f"(or a sidecar) and another --db{scale}")


#: No property given: each object keeps its own.
NO_PHYSICAL = Physical()
