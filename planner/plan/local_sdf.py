"""The object around a grasp, as the p_hold model reads it: the measure
``local_sdf`` (issue 26).

The grip measures (:mod:`planner.plan.grip`) say how the object sits between
the fingers in a few numbers; what decides whether a grasp survives a shake
also depends on the shape around them in ways no few numbers say (a rim
that the fingers hook under, a body that fills the jaw or leaves it hollow,
a handle beside a pad). ``local_sdf`` is that shape, sampled: the object's
signed distance [m] (negative inside) at a grid of
:data:`~planner.specs.hand_spec.LOCAL_CELLS` points fixed in the hand frame
(``[local_sdf]`` of hand.toml, :class:`~planner.specs.hand_spec.LocalGrid`),
clipped to +-:data:`CLIP` and rounded to :data:`DIGITS` decimals (0.1 mm:
the stored value and the one the model reads at planning time are the
same number). The surface closing collides with gives it: the exact mesh,
or for a mesh with more faces than the collision proxy's threshold
(:mod:`planner.geometry.proxy`) its proxy, within the proxy's stated
deviation (0.22 mm on a 100k-face scan) and at the cost of a small mesh's
(2.15 ms a grasp on the exact 100k faces, bench/RESULTS.md); the sign from
:meth:`planner.geometry.distance.MeshDistance.signed`: the pseudonormals where
they are exact, the winding number where bodies overlap (the nearest face
can be one body's, inside another: the pseudonormal calls that point
outside) or the mesh is open.

Measured against ACRONYM's FleX labels on the dev set's tuning objects
(grouped by object, bench/RESULTS.md), the model's trees read it beside the
other measures.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from planner.specs.hand_spec import LOCAL_CELLS, LocalGrid

if TYPE_CHECKING:
    import trimesh

    from planner.geometry.distance import MeshDistance
    from planner.specs.hands import HandSpec

#: [m] distances beyond +-CLIP are all "far outside" / "deep inside".
CLIP = 0.02
#: Decimals kept [m]: 0.1 mm.
DIGITS = 4

__all__ = ["CLIP", "DIGITS", "LOCAL_CELLS", "LocalSurface", "measure", "measured_together"]


class LocalSurface:
    """The surface ``local_sdf`` reads for one object and hand (``mesh``: the
    one closing collides with, see the module docstring); nothing to measure
    where the hand declares no grid."""

    def __init__(self, hand: HandSpec, mesh: trimesh.Trimesh) -> None:
        from planner.geometry.distance import MeshDistance

        self.grid = hand.local_grid
        self.surface = None if self.grid is None else MeshDistance(mesh.vertices, mesh.faces)
        self.points = None if self.grid is None else self.grid.points()  # once, not per grasp
        if self.points is not None:
            self.points.flags.writeable = False

    def of(self, pose: np.ndarray) -> np.ndarray | None:
        """:func:`measure` at ``pose``, or None for a hand without a grid."""
        if self.grid is None or self.surface is None:
            return None
        return measure(self.grid, self.surface, pose, self.points)


def measured_together(asked: Sequence[tuple[LocalSurface, np.ndarray] | None]) -> list[np.ndarray | None]:
    """:meth:`LocalSurface.of` of each (surface, pose (4, 4)) of ``asked`` (None: None), each surface's object asked
    once for all its poses: the same values, to the bit (each pose's points placed as :func:`measure` places them,
    every row of the signed distance its own point's), for one query's cost instead of one per grasp (~0.13-0.48
    ms a Panda grasp alone, ~0.05-0.3 together)."""
    out: list[np.ndarray | None] = [None] * len(asked)
    groups: dict[int, tuple[LocalSurface, list[int]]] = {}
    for k, item in enumerate(asked):
        if item is not None and item[0].grid is not None and item[0].surface is not None:
            groups.setdefault(id(item[0]), (item[0], []))[1].append(k)
    for local, rows in groups.values():
        placed = [local.points @ asked[k][1][:3, :3].T + asked[k][1][:3, 3] for k in rows]  # type: ignore[index,operator]
        values = np.round(np.clip(local.surface.signed(np.concatenate(placed)), -CLIP, CLIP), DIGITS)  # type: ignore[union-attr]
        for k, value in zip(rows, np.split(values, len(rows))):
            out[k] = value
    return out


def measure(grid: LocalGrid, surface: MeshDistance, pose: np.ndarray, points: np.ndarray | None = None
            ) -> np.ndarray:
    """(LOCAL_CELLS,) the clipped, rounded signed distance [m] of the object
    (``surface``, object frame) at the ``grid``'s points for the hand at
    ``pose`` (4, 4), hand frame in the object frame; ``points``: the grid's
    :meth:`~planner.specs.hand_spec.LocalGrid.points`, when already made."""
    points = (grid.points() if points is None else points) @ pose[:3, :3].T + pose[:3, 3]
    return np.round(np.clip(surface.signed(points), -CLIP, CLIP), DIGITS)
