"""Which grasps rank first, declared once (issue 26): a 1 in one of :data:`FIRST` ranks a grasp above every grasp
without one, whatever the scores. The database's SQL (:func:`planner.db.ranking.first_sql`) and records' order
(:func:`planner.db.ranking.rank_order`), the selections of "the grasps that rank first" (``grasp validate
--force-closure``, the viewer's filter, the report) and planning's choice of the grasps a unit reaches
(:func:`planner.plan.unit.add_reachability`) all read it here, the record floor every stage may import."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from planner.record import fields

if TYPE_CHECKING:
    from planner.record.grasp import Grasp

#: The record attribute and measure name (1/0; NULL, None, absent: 0) of a grasp whose squeeze's end is stored as a
#: grasp of its own beside it (the same unit and candidate, :mod:`planner.plan.keeping`: force closure as planned at the
#: turned pose): :attr:`planner.record.grasp.Grasp.end_kept`, in SQL :func:`planner.db.ranking.end_kept_sql`.
END_KEPT = "end_kept"
#: The measures (0/1, NULL: not measured) of which a 1 ranks a grasp above every grasp without one, whatever the
#: scores (issue 26), each with the measure whose 1 takes that back ('' none): force closure as planned, or as a
#: parallel jaw's squeeze ends in (planner.plan.squeeze: where the planned contacts are not force closure, the free
#: object would turn between the pads; on the 46 tuning files FleX held 68.5% of the closed poses that are force
#: closure after the squeeze and 62.5% of the others, against 52.9% of those force closure as planned and 75.1% of
#: the others, bench/RESULTS.md 2026-12-07) unless that squeeze's end is stored (:data:`END_KEPT`): the end stands
#: for it, and it ranks after every grasp that ranks first, by its score among the others (it ranked beside its end,
#: p_hold within 0.0001-0.005: 9 of held_out_4's 470 top-10 Panda grasps were such parents, issue 26's "no top-10
#: grasp whose planned contacts are not force closure"). A grasp force closure only once squeezed without a stored
#: end (an import's: imports keep exactly the poses given) still ranks first.
FIRST = {"force_closure": "", "squeezed_force_closure": END_KEPT}


def _flags(measures: Mapping[str, ArrayLike | None], name: str, n: int) -> np.ndarray:
    """(n,) bool: measure ``name`` > 0 (NaN, None or a measure not given: 0)."""
    values = measures.get(name)
    if values is None:
        return np.zeros(n, bool)
    array = np.array([np.nan if v is None else v for v in values], float) if isinstance(values, (list, tuple)) \
        else np.asarray(values, float)
    return np.nan_to_num(array) > 0


def ranks_first(measures: Mapping[str, ArrayLike | None]) -> np.ndarray:
    """(n,) bool: the grasps a 1 in one of :data:`FIRST` ranks first, unless its measure that takes it back is 1
    (``measures`` by those names, each (n,); NaN or None or a measure not given: 0; ``force_closure`` required: its
    length is n)."""
    n = len(measures["force_closure"])  # type: ignore[arg-type]
    return np.any([_flags(measures, name, n) & ~_flags(measures, back, n) for name, back in FIRST.items()], axis=0)


def first_measures(grasps: Sequence[Grasp]) -> dict[str, list]:
    """The measures of :data:`FIRST` of grasp records, by name (None: not measured), and :data:`END_KEPT`."""
    return {**{name: fields.values(fields.by_name(name), grasps) for name in FIRST},
            END_KEPT: [g.end_kept for g in grasps]}


def first_of(grasps: Sequence[Grasp]) -> list[bool]:
    """Which grasp records rank first (:func:`ranks_first`: force closure as planned, or once squeezed where that
    squeeze's end is not stored beside it); what a selection of "the grasps that rank first" keeps (``grasp
    validate --force-closure``, the viewer's filter, the grasps a unit reaches)."""
    return ranks_first(first_measures(grasps)).tolist() if grasps else []
