"""Every numerical tolerance of the grasp-quality package, in one place.

Wrench units: a primitive wrench has a unit normal force component, so the
force part is in newtons per newton of normal force and the torque part, after
division by the torque scale rho, is too.  Tolerances in "wrench units" are
therefore dimensionless multiples of the normal force.
"""

from __future__ import annotations

#: Weight resistance above this many g counts as this many: on the record floor (what is said of a stored value
#: reads it there without loading this package's scipy).
from planner.record.tolerances import RESISTANCE_CAP  # noqa: F401 - re-exported

#: A grasp is force closure iff its L1 epsilon exceeds this (wrench units).
#: ``force_closure`` and ``epsilon`` decide with this single number, so
#: ``force_closure(...) == (epsilon(...) > 0)`` always.  1e-9 is OpenRAVE's
#: threshold; it sits far above qhull round-off (~1e-15) and far below any
#: grasp worth keeping.
FORCE_CLOSURE_TOL = 1e-9

#: A wrench that lies beyond a hull facet's plane by less than this times the
#: largest wrench coordinate counts as on the plane (about 500 ulps).  It bounds
#: the error of the active-set epsilon.
FACET_TOL = 1e-13

#: A merged ('Qx') or joggled ('QJ') qhull hull is accepted when no point lies
#: beyond a facet and no facet vertex lies off its plane by more than this
#: times the largest wrench coordinate; the hull is then within this distance
#: of the true one, so the volume is off by at most HULL_TOL * scale * surface
#: area.  Only inputs on which the unmerged 'Q0' fails get here (nearly
#: coincident wrenches); 'QJ' joggles by ~1e-10 of the largest coordinate
#: after its retries on them, hence 1e-9.
HULL_TOL = 1e-9

#: Centrum radius (times the largest wrench coordinate) of the qhull attempt
#: 'Qx C-r': pre-merging facets this close to coplanar gets qhull past the
#: "wide merge due to dupridge" stop on the Minkowski sums of nearly coplanar,
#: symmetric contacts, ~1e-13 accurate where 'QJ' would give ~1e-10.
MERGE_RADIUS = 1e-12

#: Last resort of qhull when every option fails (topology errors, or 'QJ'
#: joggled by more than HULL_TOL) on wrenches nearly coincident but farther
#: apart than DEDUP_TOL: the edges of a mu = 1e-12 cone lie ~1e-12 from each
#: other, soft torsion columns ~torsion / rho (2e-10 for 1e-11 m) from the
#: normal.  Wrenches closer than r times the largest wrench coordinate are
#: clustered, for r = this times 1e-3, 1e-2, 1e-1, 1 in turn, and the hull is
#: built on one wrench per cluster.  It is accepted only if no wrench lies
#: beyond it by more than r plus the accepted error of its options (FACET_TOL
#: or HULL_TOL), times the scale: its vertices are wrenches, so it lies inside
#: the true hull (to HULL_TOL), and epsilon is then within (CLUSTER_RADIUS +
#: HULL_TOL) * scale of the true value, the volume within that times the
#: surface area (to first order).  The error is measured, not assumed: ~1e-12
#: when only mu = 1e-12 cones merge, ~mu when whole mu = 1e-9 cones do.
#: 1e-8: a mu = 1e-9 cone (edges <= 2e-9 apart) is one cluster whatever the
#: number of edges (a radius near 1e-9 splits it, and may fail), and 1e-8 is far
#: below the wrench differences of a real grasp (mu >= 1e-3, torsion >= 1e-4
#: m, contacts a micrometre apart: all >= 1e-5).  A hull decides force closure
#: only when the certificates are inconclusive (epsilon within a small factor
#: of FORCE_CLOSURE_TOL) and then, for more than 24 wrenches, only if the
#: active set fails too; a clustered hull overstates epsilon by at most
#: HULL_TOL * scale, as a merged one does.
CLUSTER_RADIUS = 1e-8

#: Primitive wrenches whose coordinates agree to this times the largest wrench
#: coordinate are merged before any hull (mu = 0 cones, repeated contacts).
DEDUP_TOL = 1e-12

#: Allowed deviation of R_i^T R_i from the identity: normals and tangents must
#: be unit and orthogonal to this accuracy (float32 frames pass).
FRAME_TOL = 1e-6

#: Relative residual above which an NNLS solution is read as "this direction is
#: not in the positive span" and its residual is tried as a separating plane.
NNLS_RESIDUAL_TOL = 1e-12

#: An inscribed simplex whose barycentric matrix has a worse condition number
#: than this is not trusted as a force-closure certificate.
SIMPLEX_COND_MAX = 1e8

#: contact_forces: accepted equilibrium error |G f + w_ext| relative to
#: max(1, |w_ext|), and accepted friction-cone violation |f_t| - mu f_n
#: relative to max(1, |f|).
EQUILIBRIUM_TOL = 1e-6
CONE_TOL = 1e-6

#: contact_forces: smoothing d of the cone constraint mu f_n - sqrt(|f_t|^2 +
#: d^2) + d >= 0, in units of the largest external wrench component; the
#: smoothed cone exceeds the true one by at most d, far inside CONE_TOL.
CONE_SMOOTHING = 1e-9

#: Singular values below this times the largest count as zero when finding the
#: linear span of a partial Minkowski sum (the L-infinity GWS).
RANK_TOL = 1e-12

#: Relative asymmetry / negative eigenvalue accepted in an inertia tensor.
INERTIA_TOL = 1e-9

#: [m/s^2] standard gravity: weight resistance is in units of the object's weight m g.
GRAVITY = 9.81

#: The batched dual simplex of the weight resistance (:mod:`planner.quality.resistance_batch`): a basic value
#: above -LP_TOL, the values (the negative ones set to 0) solving each row to LP_TOL of that row's own terms, and a
#: reduced cost above -LP_TOL, count as feasible and optimal. HiGHS's own feasibility tolerances are 1e-7; a basis
#: that passes at 1e-9 gives the optimum to ~1e-10 g.
LP_TOL = 1e-9
#: ... and a basic value within LP_ROUNDOFF x the largest of 0 is round-off of B^-1 b, a 0, where each row is
#: checked on its own terms: the Barrett's mug unit's programs pass from 1e-15 on (values ~1e-16 of the largest in
#: its degenerate motor rows of bound 0, whose every term is 0); the slack of -5.6e-10 that gave 50 g for 0 was
#: 8.6e-10 of the largest.
LP_ROUNDOFF = 1e-12
#: ... and a pivot smaller than LP_PIVOT_TOL x the largest entry of its row is not taken: a smaller one blew a
#: Barrett program's tableau up to inf (its answer then came from HiGHS, but after a detour).
LP_PIVOT_TOL = 1e-7
#: ... and a certificate of infeasibility (a row y of B^-1 with y A >= 0, y b < 0) holds where each y A_j is at
#: least -FARKAS_TOL x max |y| x sum |A_j| (its round-off: down to -3e-16 on the 5,870 certificates of the Panda's,
#: Barrett's and Allegro's mug units and the PR2's duck). At LP_TOL one of -1.8e-8, a generator 1e-9 from parallel
#: to another, passed: the program held 50 g with forces of ~1e7 N, and was given 0.
FARKAS_TOL = 1e-12
