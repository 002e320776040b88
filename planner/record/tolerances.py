"""The thresholds that give the stored feasibility its meaning, in one place.
Planning flags a grasp with them (:mod:`planner.plan.measures`: ``open_limit``,
``at_close_stop``), the ranking's gate reads them (:mod:`planner.db.ranking`)
and the shake trial refuses to simulate a grasp without clearance
(:mod:`planner.validation.shake`): three stages, one number each, so they
live on the record floor below all three. Lengths in metres."""

from __future__ import annotations

#: [m] a finger touching closer than this to its open limit has no clearance:
#: the open hand cannot be placed around the object (the shake trial flags
#: below it too; cross-validation on the tuning objects chose 2 mm for the
#: Barrett, 0-3 mm for the Panda, see bench/RESULTS.md).
MIN_OPEN_MARGIN = 0.002
#: [m] a finger this close to its closing stop cannot squeeze.
MIN_CLOSE_MARGIN = 1e-4

#: Weight resistance above this many g counts as this many (:mod:`planner.quality.resistance`): contacts on
#: links no joint moves (the palm) are pushed by the arm and bound nothing, and a grasp that holds 50 g holds
#: any load a shake test or a robot arm applies. Here, below the quality library, since a stored value at it
#: is a bound, not a measurement, and what shows one says so (:mod:`planner.present.describe`).
RESISTANCE_CAP = 50.0
