"""How much of each object's surface the contacts of its best grasps cover
(``grasp report`` prints it): of an even sample of the surface, the fraction
within :data:`~planner.db.diverse.COVERAGE_RADIUS` of a contact of the top K
grasps, plain rank order and diverse (:mod:`planner.db.diverse`)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from planner.db.diverse import COVERAGE_RADIUS, Spacing, coverage, diverse
from planner.db.objects import stored_object
from planner.db.store import open_db
from planner.specs.hands import load_hand

if TYPE_CHECKING:
    import trimesh

SURFACE_SAMPLES = 4000  # surface points per object (an even sample, fixed seed)


@dataclass(frozen=True)
class Coverage:
    """Surface coverage of one object's top ``top`` grasps for one hand."""

    object: str
    hand: str
    top: int
    ranked: float  # fraction of the surface covered by the top K by rank
    diverse: float  # ... by the top K diverse ones
    grasps: int  # how many grasps were available (at most K count)

    def line(self) -> str:
        return (f"coverage {self.object}/{self.hand}: top-{self.top} contacts cover {100 * self.ranked:.1f}% of the "
                f"surface, top-{self.top} diverse {100 * self.diverse:.1f}% (within {COVERAGE_RADIUS * 1000:.0f} mm;"
                f" {self.grasps} grasps)")


def coverages(db_path: Path, top: int = 10, spacing: Spacing | None = None, seed: int = 0) -> list[Coverage]:
    """:class:`Coverage` of every (object, hand) with ranked grasps in the database."""
    spacing = spacing or Spacing()
    out = []
    with open_db(Path(db_path), create=False, readonly=True) as db:
        for obj_name, hand in sorted(db.pairs()):
            row = db.object_row(obj_name)
            ranked = db.best(obj_name, hand, top)
            if row is None or not ranked:
                continue
            spec = load_hand(hand)
            batches = db.grasp_batches(obj_name, hand, size=500)
            try:
                apart = diverse((g for b in batches for g in b if g.rank), top, spacing, spec.tcp, spec.approach,
                                spec.roll_symmetry)
            finally:
                batches.close()
            mesh = stored_object(row).mesh
            surface = _even_samples(mesh, seed)
            points = lambda gs: np.vstack([g.contacts.points for g in gs])  # noqa: E731
            out.append(Coverage(obj_name, hand, top, coverage(surface, points(ranked)),
                                coverage(surface, points(apart)), len(ranked)))
    return out


def _even_samples(mesh: trimesh.Trimesh, seed: int) -> np.ndarray:
    """About :data:`SURFACE_SAMPLES` points spread evenly on ``mesh``
    (trimesh's even sampler, which keeps fewer where they would crowd and
    says so in a warning: the count is not what coverage needs, their
    spread is)."""
    import logging

    import trimesh

    quiet = logging.getLogger("trimesh")
    level = quiet.level
    quiet.setLevel(logging.ERROR)
    try:
        return trimesh.sample.sample_surface_even(mesh, SURFACE_SAMPLES, seed=seed)[0]
    finally:
        quiet.setLevel(level)
