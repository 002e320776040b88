"""Physical constants and tolerances of physical validation, in one place.
(The settings that decide a trial are :class:`~planner.validation.shake.ShakeSettings`,
stored with every result.)"""

from __future__ import annotations

import numpy as np

#: [m/s^2] standard gravity: a trial loads the object with its weight.
GRAVITY = 9.81
#: The load directions of a trial, in the hand frame (+-x, +-y, +-z, as
#: DexGraspNet's test): a rigid hand accelerating at a is the same as a hand
#: at rest and the object feeling -m a, so these cover a shake of the hand too.
LOAD_DIRECTIONS = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
#: [m] lever of a revolute finger with no planned contact: a fingertip's
#: typical distance from its joint.
DEFAULT_LEVER = 0.05
#: A spread joint (one that holds its preshape while the fingers close) is
#: held by a motor this many times the finger motor's effort: set by the
#: preshape, not pushed open by the grasp.
HOLD_FACTOR = 100.0
#: A gear coupling (mimic joint) may pull with up to this many times the
#: finger motor's effort: rigid, as the real gear train.
GEAR_FACTOR = 100.0
#: Smallest friction coefficient of a noisy copy (robust epsilon): a negative
#: or zero draw would be a frictionless surface, not noise.
MIN_FRICTION = 0.05
#: A soft link's contact within ``PAD_EDGE`` [m] of an edge of its collision
#: shape where faces meet at more than ``PAD_SHARP`` [rad] is on that edge
#: or corner, not on its pad face, unless the object's surface there is
#: parallel to one of those faces within ``PAD_ALIGN`` [rad] (it lies flat on
#: the pad up to its rim) (planner.validation.pads).
PAD_EDGE = 0.0015
PAD_SHARP = np.radians(30.0)
PAD_ALIGN = np.radians(10.0)
