"""The directions of gravity a grasp's weight resistance is tried in
(:mod:`planner.quality.resistance`), declared once: numpy alone, so what
only names their number (the measures' record, ``grasp best``'s text) does
not load the quality library.
"""

from __future__ import annotations

import numpy as np

#: The six axes +-x, +-y, +-z (rows, unit).
AXES = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
#: The eight cube diagonals (rows, unit).
DIAGONALS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float) / np.sqrt(3.0)
#: The axes and the diagonals: 14 unit gravity directions spread over the sphere (rows).
SPHERE14 = np.vstack([AXES, DIAGONALS])
SPHERE14.flags.writeable = False
#: How many directions the stored resistance is the worst and the mean of.
DIRECTIONS = len(SPHERE14)
