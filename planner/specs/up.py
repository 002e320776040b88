"""An object's up: the axis of its file's frame that points up as the object
stands (``+z`` unless told; ``+y`` for glTF, whose specification makes +Y up).

The object frame stays the file's: poses, contacts and exported meshes are in
it, so a user's own tools read them back. Only the physical up is the
object's: the grip measures ``com_height`` and ``gravity_arm`` (and through
them ``torque_per_mu`` and ``p_hold``), the MuJoCo trial's weight (its ``-z``
setting: the object's down, -up) and the reachability placements, which stand
the object on its up. A grasp planned on a table reads the table's up instead
(:func:`planner.geometry.frames.resting_up`).

An up is written as a sign and an axis, ``+x -x +y -y +z -z``; a bare ``x``,
``y`` or ``z`` means its ``+``, any case, blanks around it ignored.
trimesh (5.2) loads a ``.glb``/``.gltf`` as its numbers are, Y-up, without
turning it to Z-up: the default ``+y`` for them is what the file says.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from planner.errors import InputError

#: The ups an object may have, as stored and shown.
AXES = ("+x", "-x", "+y", "-y", "+z", "-z")
#: The up of an object unless told (its file's +z), and of every built-in and ``random_NNN``.
DEFAULT_UP = "+z"
#: Mesh files whose format fixes +Y as up (glTF 2.0, sec. 3.4 "Coordinate System and Units").
Y_UP_SUFFIXES = (".glb", ".gltf")
GLTF_UP = "+y"
_UNIT = {"x": 0, "y": 1, "z": 2}


def up_axis(value: object, where: str = "", name: str = "up") -> str:
    """``value`` (``+y``, ``-Z``, ``x``) as one of :data:`AXES`; a one-line :class:`InputError` naming ``where``
    (a file and line, a flag's object) and the field ``name`` (``up``, ``--up``) otherwise."""
    text = value.strip().lower() if isinstance(value, str) else ""
    text = "+" + text if text in _UNIT else text
    if text not in AXES:
        at = f"{where}: " if where else ""
        raise InputError(f"{at}{name} must be an axis of the object's file, one of {' '.join(AXES)} (x, y, z mean "
                         f"+x, +y, +z), got {value!r}")
    return text


def default_up(source: str | Path) -> str:
    """The up of a mesh file nobody gave one for: :data:`GLTF_UP` for glTF, else :data:`DEFAULT_UP`."""
    return GLTF_UP if Path(source).suffix.lower() in Y_UP_SUFFIXES else DEFAULT_UP


def up_vector(axis: str) -> np.ndarray:
    """(3,) unit vector, object frame, of one of :data:`AXES` (``+z``: (0, 0, 1))."""
    out = np.zeros(3)
    out[_UNIT[axis[1]]] = 1.0 if axis[0] == "+" else -1.0
    return out
