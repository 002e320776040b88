"""The contact reading's query of the touching pairs (:meth:`ContactReading._touching`): the whole hand's pairs,
to the last bit, asked of the exact mesh link by link and only for the links near the surface hulls."""

import numpy as np
import pytest
import scanlike

from planner import sim as sim_module
from planner.geometry.solid import load_object
from planner.plan import sampling
from planner.plan.closing import Closed, Grasper
from planner.sim import Sim
from planner.specs.hands import load_hand
from planner.specs.preshapes import load_preshapes

SEED = 3
FIELDS = ("links", "distance", "on_a", "on_b", "normal_b")


def _checked_reads(grasper: Grasper, sim: Sim, rays, shapes, obj) -> dict[str, int]:  # type: ignore[no-untyped-def]
    """Close the hand on ``rays`` with each of ``shapes``, every contact read checked against the whole hand's
    query (:meth:`Grasper._closest`) made at the same place: the same rows in the same order, one query counted
    as it counts. Returns how often the reads asked the exact mesh for the whole hand and for one link, how
    many links of the hand they did not ask, the reads, their pairs and the closed grasps."""
    seen = {"hand": 0, "link": 0, "skipped": 0, "reads": 0, "pairs": 0, "closed": 0}
    touching, rows = grasper._touching, sim._rows

    def counted(a, b, distance, link):  # type: ignore[no-untyped-def]
        if b == grasper.object_body and link is None:
            seen["hand"] += 1
        elif b == grasper.object_body:
            asked = link if isinstance(link, tuple) else (link,)
            seen["link"] += len(asked)
            seen["skipped"] += len(grasper._indices) - len(asked)
        return rows(a, b, distance, link)

    def checked(reach: float):  # type: ignore[no-untyped-def]
        before = grasper.queries
        sim._rows = counted  # type: ignore[method-assign]
        got = touching(reach)
        sim._rows = rows  # type: ignore[method-assign]
        middle = grasper.queries
        want = grasper._closest(reach)
        assert grasper.queries - middle == middle - before == 1
        for key in FIELDS:
            assert np.array_equal(getattr(got, key), getattr(want, key)), key
        seen["reads"] += 1
        seen["pairs"] += len(got)
        return got

    grasper._touching = checked  # type: ignore[method-assign]
    for i in range(len(rays)):
        for shape in shapes:
            closed = grasper.close(rays.points[i], rays.directions[i], 0.0, 0.0, shape, obj.torque_scale)
            seen["closed"] += isinstance(closed, Closed)
    return seen


@pytest.mark.parametrize("hand_name, pieces", [("panda", False), ("barrett", False), ("barrett", True)])
def test_the_touching_pairs_are_the_whole_hands_asked_only_of_the_links_near_the_hulls(
        hand_name: str, pieces: bool, tmp_path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """Seeded closings on the mug (and, for the Panda, on a 20k-face scan closed through its proxy; with
    ``pieces``, the mug's mesh added to PyBullet in pieces of 300 faces, as a mesh of more than
    :data:`~planner.sim.MESH_FACES` is): every read's pairs are the whole hand's, in its order, and the exact
    mesh is asked link by link, some links skipped, never for the whole hand."""
    if pieces:
        monkeypatch.setattr(sim_module, "MESH_FACES", 300)
    hand = load_hand(hand_name)
    shapes = load_preshapes(hand)
    path = tmp_path / "scan.obj"
    path.write_text(scanlike.uv_obj(20_000))
    for obj in [load_object("mug")] + ([load_object(str(path))] if hand_name == "panda" else []):
        rays = sampling.sample(obj.mesh, sampler="surface", count=6, rng=np.random.default_rng(SEED))
        with Sim() as sim:
            grasper = Grasper.for_object(sim, hand, obj)
            assert (grasper.object_body in sim.groups) == pieces
            seen = _checked_reads(grasper, sim, rays, shapes, obj)
        assert seen["reads"] > 0 and seen["pairs"] > 0 and seen["closed"] > 0
        assert seen["link"] > 0 and seen["skipped"] > 0  # the palm, off the hulls, not asked
        assert seen["hand"] == 0
