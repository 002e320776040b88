"""Physical constants and tolerances of physical validation, in one place.
(The settings that decide a trial are :class:`~planner.validation.shake.TrialSettings`,
stored with every result.)"""

from __future__ import annotations

import numpy as np

#: [m/s^2] standard gravity: the tugs pull with the object's weight, and the
#: object feels it while the hand shakes.
GRAVITY = 9.81
#: The six tug directions (+-x, +-y, +-z of the world), as DexGraspNet's test.
TUG_DIRECTIONS = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
#: Revolute finger offsets [rad] per prismatic one [m]: 0.01 m at a fingertip
#: ~10 cm from its joint is ~0.1 rad.
RAD_PER_M = 10.0
#: [s] the hand held still at its grasp pose after shaking, before the fingers are counted.
FINAL_HOLD = 0.1
#: Smallest friction coefficient of a noisy copy (robust epsilon): a negative
#: or zero draw would be a frictionless surface, not noise.
MIN_FRICTION = 0.05
