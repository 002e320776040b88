"""One unit of work: records for the writer, failures recorded not raised,
the contact model of each link in the score."""

from __future__ import annotations

import tempfile
from collections import Counter
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from planner import quality
from planner.datasets import importer
from planner.geometry.solid import load_object
from planner.plan import keeping, unit
from planner.plan import sweep as unit_sweep
from planner.plan.sweep import SweepSettings
from planner.plan.unit import QUALITY_FAILED, UnitSpec, grasp_quality, run_unit
from planner.quality.hull import HullError
from planner.record.contacts import HandContacts
from planner.record.grasp import Grasp
from planner.specs.hands import load_hand
from planner.specs.preshapes import load_preshapes

SETTINGS = SweepSettings(approaches=4, rolls=2, preshapes=("wide",), reach_placements=0)


@pytest.fixture(scope="module")
def box_unit():  # type: ignore[no-untyped-def]
    return run_unit(UnitSpec("box", "panda", SETTINGS, seed=1))


def test_a_unit_returns_records_of_its_object_hand_and_seed(box_unit) -> None:  # type: ignore[no-untyped-def]
    r = box_unit
    assert r.error is None and r.obj is not None and r.object_name == "box"
    wide = load_preshapes(load_hand("panda"), ["wide"])[0]
    assert r.candidates == 4 * 2 * len(wide.standoffs)  # rays x rolls x standoffs
    assert r.grasps and all(isinstance(g, Grasp) for g in r.grasps)
    assert {(g.object, g.hand, g.seed, g.preshape) for g in r.grasps} == {("box", "panda", 1, "wide")}
    assert r.candidates == len(r.grasps) + sum(r.rejected.values())
    assert [g.candidate for g in r.grasps] == sorted(g.candidate for g in r.grasps)
    assert r.force_closure == sum(g.force_closure for g in r.grasps) > 0
    assert all(g.reachability is None for g in r.grasps)  # reach_placements=0
    for g in r.grasps:
        assert g.width == pytest.approx(sum(g.closed_joints.values()))  # the Panda's two prismatic fingers
    assert set(r.timing) >= {"prepare", "sampling", "closing", "contacts", "quality"}


def test_the_same_unit_gives_the_same_grasps(box_unit) -> None:  # type: ignore[no-untyped-def]
    again = run_unit(UnitSpec("box", "panda", SETTINGS, seed=1))
    assert [(g.candidate, g.epsilon, g.pose.tolist()) for g in again.grasps] == \
        [(g.candidate, g.epsilon, g.pose.tolist()) for g in box_unit.grasps]


@pytest.mark.parametrize("sampler", ["antipodal", "surface"])
def test_a_unit_stops_at_its_share_of_the_budget_after_a_whole_point(sampler: str) -> None:
    """The budgeted unit tries a prefix of the same candidates, whole rays or
    points, and stops at the first one that begins after its share is met."""
    base = SweepSettings(approaches=24, rolls=2, sampler=sampler, preshapes=("wide",), reach_placements=0, chunk=0,
                         fc_budget=0)
    full = run_unit(UnitSpec("box", "panda", base, seed=2))
    assert full.force_closure >= 8, "the box should give enough force-closure grasps to cut"
    share = full.force_closure // 2
    cut = run_unit(UnitSpec("box", "panda", replace(base, fc_budget=share), seed=2))
    assert cut.error is None and share <= cut.force_closure < full.force_closure
    assert cut.rejected[unit.BUDGET] == full.candidates - cut.candidates > 0

    def key(g: Grasp) -> tuple:
        return g.candidate, g.pose.tolist(), g.epsilon, g.closed_joints

    # the same grasps as the full unit's first cut.candidates candidates (one unit: numbers start at 0)
    assert [key(g) for g in cut.grasps] == [key(g) for g in full.grasps if g.candidate < cut.candidates]
    per_ray = full.candidates // 24
    assert cut.candidates % per_ray == 0  # whole rays or points
    before_last = sum(g.force_closure for g in full.grasps if g.candidate < cut.candidates - per_ray)
    assert before_last < share  # it did not stop a ray or point too late


def test_failures_are_recorded_not_raised() -> None:
    assert "unknown object 'teapot'" in (run_unit(UnitSpec("teapot", "panda", SETTINGS, 0)).error or "")
    timed_out = run_unit(UnitSpec("box", "panda", SETTINGS, 0, timeout=0.0))
    assert "time-out" in (timed_out.error or "") and timed_out.object_name == "box"


def test_each_contact_is_scored_with_its_link_model() -> None:
    """Two opposed contacts: point contacts cannot resist a torque about the
    line between them, soft ones (the Panda's pads) can."""
    hand, obj = load_hand("panda"), load_object("box")
    points = np.array([[0.0, 0.02, 0.0], [0.0, -0.02, 0.0]])
    normals = np.array([[0.0, -1.0, 0.0], [0.0, 1.0, 0.0]])
    pads = HandContacts(points, normals, ("panda_leftfinger", "panda_rightfinger"))
    palm = HandContacts(points, normals, ("panda_hand", "panda_hand"))
    assert hand.contacts["panda_leftfinger"].model == "soft" and hand.contacts["panda_hand"].model == "point"
    assert grasp_quality(pads, hand, obj, 8).force_closure
    assert not grasp_quality(palm, hand, obj, 8).force_closure


def test_a_grasp_whose_quality_fails_is_rejected_with_a_counted_reason(box_unit,  # type: ignore[no-untyped-def]
                                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """A HullError on the third grasp rejects that grasp; the unit and the
    other grasps are as before."""
    calls: list[int] = []

    def failing_third(function):  # type: ignore[no-untyped-def]
        def wrapped(*args, **kwargs):  # type: ignore[no-untyped-def]
            calls.append(1)
            if len(calls) == 3:
                raise HullError("qhull precision error on a full-dimensional set")
            return function(*args, **kwargs)
        return wrapped

    # epsilon alone by default; evaluate (epsilon and volume) with --volume
    monkeypatch.setattr(quality, "epsilon", failing_third(quality.epsilon))
    monkeypatch.setattr(quality, "evaluate", failing_third(quality.evaluate))
    r = run_unit(UnitSpec("box", "panda", SETTINGS, seed=1))
    assert r.error is None and r.rejected[QUALITY_FAILED] == 1
    assert r.candidates == len(r.grasps) + sum(r.rejected.values())
    before = [(g.candidate, g.epsilon) for g in box_unit.grasps]
    assert [(g.candidate, g.epsilon) for g in r.grasps] == before[:2] + before[3:]


# -- issue 26: antipodal pairs drawn in the friction cone ------------------------

#: A quick antipodal sweep (the default sampler, rolls and depths of the Panda, fewer points); on
#: solids where most pairs are usable, stopped after the point of its first force-closure grasp.
QUICK = SweepSettings(approaches=192, chunk=0, reach_placements=0)
FIRST = SweepSettings(approaches=64, chunk=0, reach_placements=0, fc_budget=1)


def test_a_cone_gets_force_closure_grasps(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """7 cm across, 8 cm tall: no pair along the normals is inside the
    friction cone on its side; pairs drawn in the cone are (issue 26)."""
    path = tmp_path / "cone.stl"
    trimesh.creation.cone(radius=0.035, height=0.08, sections=64).export(path)
    r = run_unit(UnitSpec(str(path), "panda", QUICK, seed=0))
    assert r.error is None
    assert r.force_closure > 0
    assert any(g.force_closure and abs(g.contacts.normals[:, 2]).min() > 0.3 for g in r.grasps)  # on the tapered side


@settings(max_examples=8, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), narrow=st.floats(0.01, 0.03), wide=st.floats(0.01, 0.07),
       height=st.floats(0.03, 0.12), taper=st.floats(0.0, 0.95))
def test_random_convex_solids_narrower_than_the_opening_get_force_closure(seed, narrow, wide, height,  # type: ignore[no-untyped-def]
                                                                          taper) -> None:
    """Any convex solid narrower than the Panda's opening (8 cm) in some
    direction: the hull of 48 random points on a tapered elliptic tube (half
    axes ``wide`` and ``narrow``, 2-6 cm across the narrow one, tapering by
    ``taper`` over ``height``: slabs, wedges, cones), turned at random."""
    rng = np.random.default_rng(seed)
    t, angle = rng.uniform(0.0, 1.0, 48), rng.uniform(0.0, 2 * np.pi, 48)
    shrink = 1.0 - taper * t
    points = np.c_[wide * shrink * np.cos(angle), narrow * shrink * np.sin(angle), height * t]
    solid = trimesh.convex.convex_hull(points @ Rotation.random(random_state=seed).as_matrix().T)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "solid.stl"
        solid.export(path)
        r = run_unit(UnitSpec(str(path), "panda", FIRST, seed=0))
    assert r.error is None
    assert r.force_closure > 0, f"no force closure: {dict(r.rejected)}"



def test_a_rough_scans_force_closure_is_its_shapes(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """A rough scan (the capsule of 100k faces with 0.1 mm of noise along its normals, closed on its proxy): its
    grasps closed again from the same poses on the smooth capsule (2k faces, no proxy) are force closure or not
    alike. The sampler and the contacts read the scan's normals at a contact's scale; with its proxy's facets'
    (tilted by the noise) 271 of 362 grasps of a 64-point unit agreed, force closure on 300 against 219."""
    import scanlike

    from planner.geometry.solid import load_object
    from planner.plan.closing import Closed, Grasper
    from planner.plan.contacts import grasp_quality
    from planner.sim import Sim
    from planner.specs.hands import load_hand
    from planner.specs.preshapes import load_preshapes

    rough, smooth = tmp_path / "rough.obj", tmp_path / "smooth.obj"
    rough.write_text(scanlike.uv_obj(100_000, noise=1e-4))
    smooth.write_text(scanlike.uv_obj(2_000))
    r = run_unit(UnitSpec(str(rough), "panda", SweepSettings(approaches=12, chunk=0, reach_placements=0), 0))
    assert r.error is None and len(r.grasps) >= 40, (r.error, len(r.grasps))
    hand = load_hand("panda")
    shapes = {s.name: s for s in load_preshapes(hand)}
    obj = load_object(str(smooth))
    same = 0
    with Sim() as sim:
        grasper = Grasper.for_object(sim, hand, obj)
        for g in r.grasps:
            closed = grasper.close_from(np.asarray(g.pose), shapes[g.preshape], hand.full_configuration(g.open_joints))
            assert isinstance(closed, Closed), closed
            same += grasp_quality(closed.contacts, hand, obj, 8, False).force_closure == g.force_closure
    assert same >= 0.95 * len(r.grasps), (same, len(r.grasps), r.force_closure)


@pytest.mark.parametrize("sampler", ["surface", "box"])
def test_a_rough_scans_rays_come_in_along_its_shapes_normals(tmp_path, monkeypatch, sampler: str) -> None:  # type: ignore[no-untyped-def]
    """The ray samplers (the Barrett's, the Allegro's, the PR2's) approach a scan closed on a proxy along its
    normals at a contact's scale, as the antipodal sampler and the contacts read them: 0.1 mm of noise tilts
    its own triangles by up to tens of degrees."""
    seen = _stop_after(monkeypatch, unit.sampling, "sample")
    rough = _rough_capsule(tmp_path)
    settings = SweepSettings(approaches=200, sampler=sampler, box_delta=0.01, chunk=0, reach_placements=0)
    assert "sampled" in (run_unit(UnitSpec(str(rough), "barrett", settings, 0)).error or "")
    (rays,) = seen
    tilt = _capsule_tilt(rays.points, rays.normals)  # type: ignore[attr-defined]
    assert len(tilt) >= 100 and tilt.max() < 6.0, (len(tilt), tilt.max())


def _stop_after(monkeypatch, module: object, name: str) -> list:  # type: ignore[no-untyped-def]
    """Replace ``module.name`` by a call of it that keeps its result in the list returned, then stops the caller
    (RuntimeError "sampled")."""
    seen: list = []
    real = getattr(module, name)

    def spy(*args, **kwargs):  # type: ignore[no-untyped-def]
        seen.append(real(*args, **kwargs))
        raise RuntimeError("sampled")

    monkeypatch.setattr(module, name, spy)
    return seen


def _rough_capsule(folder: Path) -> Path:
    """The scan-like capsule of ~100k faces with 0.1 mm of noise, as an OBJ file in ``folder``."""
    import scanlike

    path = folder / "rough.obj"
    path.write_text(scanlike.uv_obj(100_000, noise=1e-4))
    return path


def _capsule_tilt(points: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Degrees between ``normals`` and the scan-like capsule's own at ``points``, those within 1 cm of a pole left
    out (there the test mesh's meridians converge: noisy vertices a few um apart, no scale of 2 mm is smooth)."""
    import scanlike

    off_pole = np.abs(points[:, 2]) < scanlike.HEIGHT / 2 + scanlike.RADIUS - 0.01
    p, normals = points[off_pole], normals[off_pole]
    axis = np.column_stack([np.zeros((len(p), 2)), np.clip(p[:, 2], -scanlike.HEIGHT / 2, scanlike.HEIGHT / 2)])
    shape = (p - axis) / np.linalg.norm(p - axis, axis=1, keepdims=True)
    return np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", normals, shape), -1, 1)))


def test_a_rough_scans_grip_measures_read_its_shapes_normals(tmp_path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """The grip measures' surface samples of a scan closed on a proxy take its normals at a contact's scale: with
    its triangles' (0.1 mm of noise), the pads of the Panda's first default unit read 0.911 aligned on average where the
    noise-free capsule at the same contacts reads 0.954 (averaged: 0.953)."""
    seen = _stop_after(monkeypatch, unit.grip, "GripSurface")
    rough = _rough_capsule(tmp_path)
    assert "sampled" in (run_unit(UnitSpec(str(rough), "panda", SETTINGS, 0)).error or "")
    with pytest.raises(RuntimeError, match="sampled"):  # an imported file's grasps are measured the same way
        importer._rescore(np.eye(4)[None], load_hand("panda"), load_object(str(rough)), Counter())
    for surface in seen:
        tilt = _capsule_tilt(surface.points, surface.normals)
        assert len(tilt) > 10_000 and np.percentile(tilt, 99.9) < 6.0, (len(tilt), np.percentile(tilt, 99.9))
    assert len(seen) == 2


def test_a_box_sampler_unit_past_its_candidates_fails_before_its_rays_are_cast(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """A batch's unit (its mesh unknown before it runs): --box-delta 0.002 --rolls 32 on the box lists 1,582,720
    candidates of a Barrett unit (a finer grid or more rolls: the worker's memory); now it fails in one line."""
    _stop_after(monkeypatch, unit.sampling, "sample")
    settings = SweepSettings(sampler="box", box_delta=0.002, rolls=32, reach_placements=0)
    error = run_unit(UnitSpec("box", "barrett", settings, 0)).error or ""
    assert "would hold 1,582,720 candidates (4,946 rays (the --box-delta grid's that meet it) x --rolls 32 x 10 " \
           "standoffs over the preshapes): at most 1,000,000" in error, error


@pytest.mark.parametrize("fan, limit, refused", [(0, 20_000, False), (2, 40_000, True)])
def test_a_box_sampler_units_bound_is_the_candidates_it_lists(monkeypatch, fan: int, limit: int,  # type: ignore[no-untyped-def]
                                                               refused: bool) -> None:
    """--box-delta 0.005 --rolls 2 on the box: 878 of the grid's 1,566 rays meet it, 17,560 Barrett candidates;
    counted by the grid (31,320) a unit under the limit was refused, and with --fan 2 (52,680) one over it passed."""
    monkeypatch.setattr(unit_sweep, "MAX_UNIT_CANDIDATES", limit)
    listed = _stop_after(monkeypatch, unit, "candidates")
    settings = SweepSettings(sampler="box", box_delta=0.005, rolls=2, fan_count=fan, reach_placements=0)
    error = run_unit(UnitSpec("box", "barrett", settings, 0)).error or ""
    assert ("would hold 52,680 candidates" in error) if refused else (error == "RuntimeError: sampled"), error
    assert [len(c) for c in listed] == ([] if refused else [17_560])


@pytest.mark.parametrize("scan", [False, True])
def test_a_workers_units_of_one_object_sample_its_surface_once(monkeypatch, tmp_path: Path, scan: bool) -> None:  # type: ignore[no-untyped-def]
    """Every unit sampled the object's whole surface (its antipodal pairs) to keep its chunk of the points: a
    worker running an object's units sampled it once per unit (a 100k-face scan: ~0.5 s each). Now once per
    object, the same grasps as units that each sample it anew; a scan (over 5,000 faces: its normals averaged
    at a contact's scale) too."""
    import scanlike

    name = "box"
    if scan:
        name = str(tmp_path / "capsule.obj")
        Path(name).write_text(scanlike.uv_obj(8_000))
    settings = SweepSettings(approaches=32, chunk=16, reach_placements=0)
    specs = [UnitSpec(name, "panda", settings, 0, chunk=c) for c in range(2)]
    monkeypatch.setattr(unit.sampling, "_SAMPLED", {})
    fresh = []
    for spec in specs:
        unit.sampling._SAMPLED.clear()
        fresh.append([(g.candidate, g.pose.tobytes()) for g in run_unit(spec).grasps])
    unit.sampling._SAMPLED.clear()
    seen = []
    real = unit.sampling.antipodal
    monkeypatch.setattr(unit.sampling, "antipodal", lambda *a, **k: seen.append(1) or real(*a, **k))
    once = [[(g.candidate, g.pose.tobytes()) for g in run_unit(spec).grasps] for spec in specs]
    assert len(seen) == 1 and once == fresh and sum(map(len, once)) > 0


def test_the_sampled_pairs_are_let_go_once_their_units_are_done(monkeypatch, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    """``api.generate`` running its units in this process (workers 1) kept the last object's antipodal pairs for
    as long as the caller lived (~120 MB at 1,000,000 points), and so did planning on the spot (``best_at``)."""
    from planner import api

    monkeypatch.setattr(unit.sampling, "_SAMPLED", {})
    settings = SweepSettings(approaches=16, reach_placements=0)
    summary = api.generate(["box"], "panda", db_path=tmp_path / "g.db", settings=settings, workers=1)
    assert summary.candidates > 0 and unit.sampling._SAMPLED == {}
    planned = unit.plan_object(load_object("box"), "panda", settings, 0)
    assert planned.candidates > 0 and unit.sampling._SAMPLED == {}


def test_a_record_that_cannot_be_made_fails_its_unit_with_its_own_error(monkeypatch: pytest.MonkeyPatch) -> None:
    """The grasps wait for their measures (``measured_later``) from the moment they are recorded: a record whose
    construction fails leaves nothing waiting for it (an index past the list, an IndexError raised in its
    place), and the grasps recorded before it are stored with their measures."""
    made: list[int] = []

    def second_fails(**fields: object) -> Grasp:
        made.append(1)
        if len(made) == 2:
            raise ValueError("no such record")
        return Grasp(**fields)  # type: ignore[arg-type]

    monkeypatch.setattr(keeping, "Grasp", second_fails)
    r = run_unit(UnitSpec("box", "panda", SETTINGS, seed=1))
    assert r.error == "ValueError: no such record"
    assert len(r.grasps) == 1 and r.grasps[0].measures is not None
