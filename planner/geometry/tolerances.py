"""Every tolerance and size limit of the geometry package, in one place."""

from __future__ import annotations

#: Relative asymmetry / negative eigenvalue accepted in an inertia tensor: the
#: tensor of a closed triangle mesh is symmetric to round-off (~1e-16 of its
#: largest entry), so 1e-9 refuses only tensors that were not computed as one.
INERTIA_TOL = 1e-9
