"""Ferrari-Canny epsilon, GWS volume and force closure (sec. 2.3.2).

The grasp wrench space (GWS) is built from the primitive wrenches W_i of
each contact (see wrenches.py):

* norm="L1":   conv(union_i W_i)            (sum of normal forces <= 1)
* norm="Linf": sum_i conv({0} U W_i)         (each normal force <= 1)

epsilon is the radius of the largest origin-centred ball inside the GWS.
Force closure is decided once, on the L1 GWS (the two GWS are force closure
together), as "L1 epsilon > FORCE_CLOSURE_TOL"; epsilon returns exactly 0.0
for grasps that fail it, so ``force_closure(...) == (epsilon(...) > 0)``.

Cost: the hull-free certificates of closure.py reject non-closure grasps in
well under a millisecond; closure grasps then pay one hull (evaluate,
volume) or an active-set hull of a few dozen wrenches (epsilon, which for
more than FULL_HULL_MAX_POINTS L1 generators runs only the certificates'
first tests before it: an active-set epsilon clear of the tolerance proves
force closure by itself).  The
L-infinity volume needs every vertex of the Minkowski sum, which grows
quickly with the number of contacts (seconds to minutes from 4 contacts
on); its epsilon does not, and ``evaluate`` takes it from the active set.

Every value is exact to the tolerances of tolerances.py or the call raises
HullError (a DegenerateGraspError) naming what failed: a hull that qhull
cannot build is never read as "flat" (0.0) nor replaced by a bound.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial import ConvexHull

from planner.quality.active_set import L1Support, LinfSupport, active_set_epsilon
from planner.quality.closure import check_closure, quick_reject
from planner.quality.contacts import ModelArg, as_center, as_contacts, as_norm, as_torque_scale
from planner.quality.hull import HullError, hull_epsilon, minkowski_points, qhull
from planner.quality.tolerances import FACET_TOL, FORCE_CLOSURE_TOL
from planner.quality.wrenches import PrimitiveWrenches, as_cone_edges, contact_wrenches, dedupe

#: Up to this many L1 generators one full hull is cheaper than the active set
#: (measured crossover: 3 point contacts x 8 edges).
FULL_HULL_MAX_POINTS = 24


@dataclass(frozen=True)
class Quality:
    """Grasp quality from one GWS hull.

    epsilon : Ferrari-Canny radius in wrench units (N per N of total normal
        force for L1, per N of largest normal force for Linf); 0.0 when not
        force closure.
    volume : GWS volume in wrench units^6; 0.0 when not force closure (the
        hull is skipped for those grasps; call ``volume`` if you need it).
    force_closure : L1 epsilon > FORCE_CLOSURE_TOL.
    """

    epsilon: float
    volume: float
    force_closure: bool


@dataclass(frozen=True)
class _Gws:
    union: np.ndarray            # (k, 6) deduplicated L1 generators
    grouped: PrimitiveWrenches   # per-contact deduplicated generators
    norm: str
    scale: float                 # largest |coordinate|, for tolerances


def _gws(points: ArrayLike, frames: ArrayLike, mu: ArrayLike, center: ArrayLike,
         torque_scale: float, cone_edges: int, model: ModelArg, norm: str,
         torsion: ArrayLike) -> _Gws:
    contacts = as_contacts(points, frames, mu=mu, model=model, torsion=torsion)
    raw = contact_wrenches(contacts, as_center(center), as_torque_scale(torque_scale),
                           as_cone_edges(cone_edges))
    norm = as_norm(norm)
    union = dedupe(raw, per_contact=False).wrenches
    grouped = dedupe(raw, per_contact=True) if norm == "Linf" else raw
    return _Gws(union, grouped, norm, max(float(np.abs(union).max(initial=0.0)), 1.0))


def _l1_epsilon(gws: _Gws) -> float:
    eps = None
    if len(gws.union) > FULL_HULL_MAX_POINTS:
        eps = active_set_epsilon(L1Support(gws.union), gws.scale)
    if eps is None:
        hull = qhull(gws.union)
        eps = 0.0 if hull is None else hull_epsilon(hull)
    return eps


def _linf_epsilon(gws: _Gws) -> float:
    """Called for force-closure grasps only, whose L-infinity GWS holds the L1
    one and so is full-dimensional."""
    eps = active_set_epsilon(LinfSupport(*gws.grouped), gws.scale)
    if eps is None:
        eps = hull_epsilon(_closure_hull(minkowski_points(*gws.grouped), gws.norm))
    return eps


def _closure_hull(points: np.ndarray, norm: str) -> ConvexHull:
    """The hull of a force-closure GWS, which holds a ball of radius >
    FORCE_CLOSURE_TOL and so is full-dimensional: qhull's None is an error."""
    hull = qhull(points)
    if hull is None:
        raise HullError(f"the {norm} GWS of a force-closure grasp came out flat: "
                        f"{len(points)} wrenches of rank < 6 to RANK_TOL")
    return hull


def _closure_lower(gws: _Gws) -> float:
    """A lower bound > TOL on the L1 epsilon, or 0.0 if not force closure."""
    check = check_closure(gws.union)
    if check.verdict is not None:
        return check.lower if check.verdict else 0.0
    eps = _l1_epsilon(gws)
    return eps if eps > FORCE_CLOSURE_TOL else 0.0


def _active_set_first(gws: _Gws) -> float | None:
    """The L1 epsilon of a GWS of more than FULL_HULL_MAX_POINTS generators
    when the active set alone proves force closure: the hull-free
    certificates' first tests (:func:`~planner.quality.closure.quick_reject`,
    0.0 if they reject), then the active set; its epsilon if that exceeds
    FORCE_CLOSURE_TOL by more than its own error (FACET_TOL * scale: the
    true epsilon then exceeds the tolerance, so no certificate can say "not
    force closure"), else None (decide as ``_closure_lower``).

    The answer ``epsilon`` gave from the certificates, max(active set,
    proven lower bound), is the active set's whenever the bound is below it,
    and the bound, the inradius of a simplex inside the GWS, never exceeds
    the true epsilon, so the two differ by at most FACET_TOL * scale: none
    of 6,377 recorded force-closure grasps (Panda box, mug, duck and
    random_003, Barrett mug and duck units) had a bound above the active
    set's epsilon (at most 0.96 of it).  The certificates' other 6 NNLS
    (~0.4 ms a force-closure grasp) are skipped."""
    if len(gws.union) <= FULL_HULL_MAX_POINTS:
        return None
    if quick_reject(gws.union):
        return 0.0
    eps = active_set_epsilon(L1Support(gws.union), gws.scale)
    return eps if eps is not None and eps > FORCE_CLOSURE_TOL + FACET_TOL * gws.scale else None


def epsilon(points: ArrayLike, frames: ArrayLike, *, mu: ArrayLike, center: ArrayLike,
            torque_scale: float, cone_edges: int = 8, model: ModelArg = "point",
            norm: str = "L1", torsion: ArrayLike = 0.0) -> float:
    """Ferrari-Canny epsilon of the grasp; 0.0 when not force closure.

    points : (n, 3) c_i [m]; frames : (n, 3, 3) R_i, columns (n_i, l_i, o_i)
    with n_i into the object; mu, torsion [m] : scalar or (n,); center : (3,)
    p [m]; torque_scale : rho [m]; model : name or n names from MODELS;
    norm : "L1" or "Linf".  Raises DegenerateGraspError on malformed input,
    HullError (one of them) if qhull cannot build a hull it needs.
    """
    gws = _gws(points, frames, mu, center, torque_scale, cone_edges, model, norm, torsion)
    first = _active_set_first(gws) if gws.norm == "L1" else None
    if first is not None:
        return first
    lower = _closure_lower(gws)
    if lower <= 0.0:
        return 0.0
    eps = _l1_epsilon(gws) if gws.norm == "L1" else _linf_epsilon(gws)
    return max(eps, lower)      # lower is proven; this only guards round-off


def force_closure(points: ArrayLike, frames: ArrayLike, *, mu: ArrayLike, center: ArrayLike,
                  torque_scale: float, cone_edges: int = 8, model: ModelArg = "point",
                  norm: str = "L1", torsion: ArrayLike = 0.0) -> bool:
    """True iff the L1 epsilon exceeds FORCE_CLOSURE_TOL, decided by hull-free
    certificates (a hull only when they are inconclusive, i.e. epsilon within
    a small factor of the tolerance).  ``norm`` does not change the answer."""
    gws = _gws(points, frames, mu, center, torque_scale, cone_edges, model, norm, torsion)
    return _closure_lower(gws) > 0.0


def volume(points: ArrayLike, frames: ArrayLike, *, mu: ArrayLike, center: ArrayLike,
           torque_scale: float, cone_edges: int = 8, model: ModelArg = "point",
           norm: str = "L1", torsion: ArrayLike = 0.0) -> float:
    """GWS volume (wrench units^6) whether or not the grasp is force closure;
    0.0 when the GWS is not full-dimensional.  Arguments and errors as
    ``epsilon``.  Exact to round-off, or within HULL_TOL * scale * surface
    area when qhull needed merging or joggling (nearly coincident wrenches)."""
    gws = _gws(points, frames, mu, center, torque_scale, cone_edges, model, norm, torsion)
    hull = qhull(gws.union if gws.norm == "L1" else minkowski_points(*gws.grouped))
    return 0.0 if hull is None else float(hull.volume)


def evaluate(points: ArrayLike, frames: ArrayLike, *, mu: ArrayLike, center: ArrayLike,
             torque_scale: float, cone_edges: int = 8, model: ModelArg = "point",
             norm: str = "L1", torsion: ArrayLike = 0.0) -> Quality:
    """epsilon, volume and force closure together: certificates first (no
    hull for non-closure grasps), then one hull (L1: epsilon and volume from
    it; Linf: the volume, with epsilon from the same active set as
    ``epsilon``).  Arguments as ``epsilon``; raises HullError if a hull
    cannot be built."""
    gws = _gws(points, frames, mu, center, torque_scale, cone_edges, model, norm, torsion)
    lower = _closure_lower(gws)
    if lower <= 0.0:
        return Quality(0.0, 0.0, False)
    if gws.norm == "L1":
        hull = _closure_hull(gws.union, gws.norm)
        return Quality(max(hull_epsilon(hull), lower), float(hull.volume), True)
    eps = _linf_epsilon(gws)
    hull = _closure_hull(minkowski_points(*gws.grouped), gws.norm)
    return Quality(max(eps, lower), float(hull.volume), True)
