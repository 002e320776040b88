"""Every tolerance and physical limit of the planning stages, in one place,
each with its reason. Lengths in metres, angles in radians. (The step sizes
of closing are settings: :class:`~planner.plan.closing.CloseSettings`.)"""

from __future__ import annotations

import numpy as np

#: A hand link deeper than this inside the object rejects a grasp (closing)
#: or an arm solution at the grasp (reachability): 1 mm is within PyBullet's
#: margins once corrected, deeper is a real overlap.
MAX_PENETRATION = 0.001
#: Contact points of one link closer than this are one contact (a pad touches
#: a face in a patch; two points 2 mm apart add no independent wrench).
MERGE_RADIUS = 0.002
#: At most this many contacts per link, spread over its contact patch: four
#: span a flat pad's patch.
MAX_PER_LINK = 4
#: Soft-finger torsion per unit normal force of a flat disc of radius a under
#: uniform pressure: 2/3 mu a (the integral of mu r p over the disc).
SOFT_TORSION = 2.0 / 3.0
#: Closest-point pairs closing in slower than this (per unit travel) count as
#: sliding past: their distance cannot fall to zero within a step.
CLOSING_SPEED_MIN = 0.05
#: A joint this close to its limit (in joint units) has no room left; also the
#: slack of limit checks, so values on a limit pass after round-off.
JOINT_LIMIT_SLACK = 1e-9
#: [m] A link whose gap to the exact mesh is below closing's ``near`` by this much is near the surface hulls
#: (:meth:`planner.plan.obstacle_queries.ObstacleQueries._closest_near`): the hulls contain the surface, so
#: their gap is the smaller; PyBullet's margins and round-off put a hull's gap at most ~0.02 mm above the
#: mesh's where both touch a finger (the peer's scan), this many times over.
NEAR_SLACK = 0.0005
#: [m] How far PyBullet's gap of a link to the surface hulls may stray from the change its motion allows (a finger's
#: bracket of that gap, :class:`planner.plan.obstacle_queries.HullBracket`): GJK converges to ~1e-9 m here.
BRACKET_SLACK = 1e-5
#: The OpenRAVE box sampler grows the object's bounding box by this much.
BOX_MARGIN = 0.01
#: Antipodal sampler: a chord thinner than this is a sliver or a skin, not
#: something to pinch (and the ray may have met the next triangle of the same
#: face); the ray to the opposite side starts this far inside the surface
#: (embree works in float32: ~1e-8 m of round-off near the object).
MIN_CHORD = 0.002
RAY_START = 1e-6
#: Antipodal sampler: the fingers open to the chord plus this much per side
#: (the full opening of a wide gripper straddling a thin wall puts the inner
#: finger through the far side of a cup), within the preshape's opening; a
#: preshape takes a chord when its opening exceeds the chord by this much per side.
FINGER_CLEARANCE = 0.01
MIN_CLEARANCE = 0.002

#: Pre-grasp: the hand backed off this far along its approach, fingers open.
PREGRASP_DISTANCE = 0.10
#: An arm solution counts when forward kinematics puts the end effector this
#: close to the target: 1 mm and 0.5 degree.
POSITION_TOL = 1e-3
ANGLE_TOL = float(np.radians(0.5))
#: IK is re-run from its own answer until within this fraction of the
#: tolerances (so the verified solution has margin), at most IK_REFINEMENTS times.
IK_CONVERGED = 0.25
IK_REFINEMENTS = 6
#: The arm backs off from the grasp to the pre-grasp by interpolating its
#: joints: at each of PATH_STEPS - 1 points between, the hand stays within
#: PATH_TOL times the back-off distance (at least POSITION_TOL: a back-off
#: of 0 has no line) of the straight approach line and
#: within PATH_ANGLE [rad] of the grasp's orientation. Measured (the PR2's
#: arm, the mug at 4 poses, 10 cm): 3.1 mm median, 4.2 at most, 1.3 degrees;
#: the Panda's, 3.0 mm, 7.0 at most, 1.0 degree (bench/RESULTS.md); a
#: pre-grasp on another IK branch (the elbow flipped) swings the hand 1.2 m
#: off the line.
PATH_STEPS = 8
PATH_TOL = 0.2
PATH_ANGLE = float(np.radians(10.0))
#: The table: a box with these half extents (x, y, thickness), its far edge
#: reaching 0.9 of its length in front of the robot base (the base at its edge).
TABLE_HALF = (1.0, 1.0, 0.05)
TABLE_REACH = 0.9
#: Where the spare hand used for table checks waits, far from everything.
PARKING_DEPTH = 100.0
#: Planning on a table (closing's obstacle): a slab with these half extents
#: (x, y, thickness) whose top is the table top, thick enough that a hand
#: anywhere under the top overlaps it.
TABLE_SLAB = (1.0, 1.0, 0.5)
#: Grasps planned on a table keep the hand this far above its top: the reach
#: check counts touching as a hit, and PyBullet's distances between convex
#: shapes are good to a fraction of a millimetre.
TABLE_CLEARANCE = 0.002
#: Approach rays on a table come down onto it at least this steeply (ray
#: samplers turn shallower ones down): a level approach low over the table
#: puts the arm's wrist through it (the KUKA's links 5 and 6 under a Barrett
#: at 5 cm, measured), and the planner sees the hand alone.
TABLE_ELEVATION = float(np.radians(30.0))
#: An approach stopped by the table backs off this far along itself before the
#: fingers close: a fingertip resting on the table would count as touching and
#: never move (at 30 degrees down, the hand rises 2 mm).
TABLE_LIFT = 0.004

#: Rays straight down onto an object on a table (:func:`planner.plan.sampling.from_above`): through
#: the centre of mass, and through the footprint's centre +- ``ABOVE_SPREAD`` of its length along its
#: long side; each ``ABOVE_PHASES`` times, its rolls turned by successive ``ABOVE_TURN`` [rad] (with the
#: sweep's quarter turns, a roll every 30 degrees: a table pinch's fingers must straddle the object).
ABOVE_POINTS = 3
ABOVE_PHASES = 3
ABOVE_TURN = float(np.pi / 6)
ABOVE_RAYS = ABOVE_POINTS * ABOVE_PHASES
ABOVE_SPREAD = 0.25
