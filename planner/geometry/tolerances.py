"""Every tolerance and size limit of the geometry package, in one place."""

from __future__ import annotations

#: Relative asymmetry / negative eigenvalue accepted in an inertia tensor: the
#: tensor of a closed triangle mesh is symmetric to round-off (~1e-16 of its
#: largest entry), so 1e-9 refuses only tensors that were not computed as one.
INERTIA_TOL = 1e-9

#: [m] How far outside its mesh's convex hull a given centre of mass may lie: the hull's planes are exact to
#: round-off of a mesh a few centimetres across (~1e-17 m); 1 um keeps a centre given on a face (a cube's, to the
#: micrometre a sidecar is written to) and refuses any that is visibly outside.
HULL_TOL = 1e-6
