"""Where a unit's CPU goes, per candidate OUTCOME (issue 24: what share of a sweep buys no force-closure grasp).

    python bench/outcomes.py [--hand panda] [--objects mug duck box random_002 random_005 random_007]
                             [--approaches 256] [--json-out FILE] [--cprofile DIR] [--mass KG] [--friction MU]

An object is a built-in's name or a mesh file (the peer's scan: ``--objects
~/.cache/grasp-planner/peer-venv/share/pybullet_grasper/objects/object_0.obj --mass 0.5 --friction 0.5``, as
``bench/peer.py`` runs it; ``--mass``/``--friction``: every object's, default its own).

Per object, one unit of the hand's default sweep as ``bench/labelled_rate.py`` runs it (``--approaches`` points
or rays, one unit, no reachability; the object's collision proxy made before the clock starts), in this process.
Every candidate's CPU (``time.process_time``, from the moment it is taken to the next one: its rejection test,
closing, contacts and scoring) goes to its outcome: ``rej:REASON`` (the sweep's ``rejected`` counter: refused
pairs ``cone``, ``too_wide``..., ``overlap`` before closing; ``penetration``, ``no_contact``... after it),
``closed_notFC`` (stored, not force closure as planned) or ``FC``. Three pieces are taken out of those intervals
and shown on their own: the squeeze (:func:`planner.plan.squeeze.squeezed`, only of grasps not force closure), and
the deferred measures (:func:`planner.plan.measures.measure` per grasp, split by force closure, and the batched
weight resistances). ``--cprofile DIR`` also writes each object's cProfile stats there (the timings then include
its overhead). The instrumentation wraps the unit module's names for the run only: the grasps are the sweep's.

Beside the outcomes, per stage (:data:`STAGES`: closing the fingers, the contact reading's query, its patches,
moving them onto a proxied scan's exact surface, epsilon, the grip measures, ``local_sdf``, the resistance
programs; CPU inside each, nested stages not taken out) and per simulator query kind (the stage that asked; the
object's mesh or proxy, or another body: the surface hulls of closing's far field, a table; the whole hand or one
link): count, rows returned, CPU.
"""

from __future__ import annotations

import argparse
import cProfile
import json
import time
from collections import Counter, defaultdict
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

clock = time.process_time
DEFAULT_OBJECTS = ("mug", "duck", "box", "random_002", "random_005", "random_007")
#: planner.plan.unit.BUDGET (not imported: ``--help`` without the planner's imports).
BUDGET = "budget"
#: Pieces timed on their own, out of the candidates' intervals.
PIECES = ("squeeze", "measure", "resist")
#: Stages timed inside the candidates (name, module, owner in it, attribute).
STAGES = (("closing", "planner.plan.finger_closing", "FingerClosing", "_close_fingers"),
          ("contact query", "planner.plan.contact_reading", "ContactReading", "_touching"),
          ("patches", "planner.plan.contact_reading", "ContactReading", "_patches"),
          ("onto exact", "planner.plan.contact_reading", "ContactReading", "_onto_exact"),
          ("epsilon", "planner.plan.keeping", None, "grasp_quality"),
          ("grip", "planner.plan.grip", None, "measure"),
          ("local_sdf", "planner.plan.local_sdf", "LocalSurface", "of"),
          ("local_sdf", "planner.plan.local_sdf", None, "measured_together"),
          ("resistance", "planner.plan.keeping", None, "resistance_program"),
          ("resistance", "planner.plan.measures", None, "resistances"))


def outcome(before: Counter, after: Counter, grasps: list, stored_before: int) -> str:
    """The outcome of one candidate from the unit's ``rejected`` counter ``before`` and ``after`` it and its
    grasps (``stored_before`` of them before it): ``FC``, ``closed_notFC``, ``rej:REASON``, or ``none`` (counted
    nowhere: a candidate the sweep skipped). The candidates left untried once the budget is spent
    (:data:`~planner.plan.unit.BUDGET`, counted when the next would begin) are no candidate's outcome."""
    if len(grasps) > stored_before:
        return "FC" if grasps[-1].force_closure else "closed_notFC"
    grown = [reason for reason in after if after[reason] > before.get(reason, 0) and reason != BUDGET]
    return f"rej:{grown[0]}" if len(grown) == 1 else "none"


class Ledger:
    """CPU [s] and count per outcome, and the pieces' CPU [s] (``measure``'s per call, in call order)."""

    def __init__(self) -> None:
        self.cpu: defaultdict[str, float] = defaultdict(float)
        self.count: Counter = Counter()
        self.pieces: defaultdict[str, float] = defaultdict(float)
        self.measure_calls: list[float] = []
        self._open: tuple[float, Counter, int] | None = None
        self._taken = 0.0  # pieces' CPU inside the open candidate's interval
        self.stages: defaultdict[str, float] = defaultdict(float)
        self.queries: defaultdict[str, list] = defaultdict(lambda: [0, 0, 0.0])  # kind: [count, rows, CPU s]
        self._within: list[str] = []  # the stages open now, innermost last

    def begin(self, result) -> None:  # type: ignore[no-untyped-def]
        self.end(result)
        self._open, self._taken = (clock(), result.rejected.copy(), len(result.grasps)), 0.0

    def end(self, result) -> None:  # type: ignore[no-untyped-def]
        if self._open is None:
            return
        start, before, stored = self._open
        key = outcome(before, result.rejected, result.grasps, stored)
        self.cpu[key] += clock() - start - self._taken
        self.count[key] += 1
        self._open = None

    def timed(self, name: str, fn: Callable) -> Callable:
        def wrapper(*args, **kwargs):  # type: ignore[no-untyped-def]
            t = clock()
            try:
                return fn(*args, **kwargs)
            finally:
                spent = clock() - t
                self.pieces[name] += spent
                self._taken += spent if self._open is not None else 0.0
                if name == "measure":
                    self.measure_calls.append(spent)
        return wrapper

    def staged(self, name: str, fn: Callable) -> Callable:
        def wrapper(*args, **kwargs):  # type: ignore[no-untyped-def]
            t = clock()
            self._within.append(name)
            try:
                return fn(*args, **kwargs)
            finally:
                self._within.pop()
                self.stages[name] += clock() - t
        return wrapper

    def queried(self, fn: Callable) -> Callable:
        def rows(sim, a, b, distance, link):  # type: ignore[no-untyped-def]
            t = clock()
            found = fn(sim, a, b, distance, link)
            target = "mesh" if b in sim.meshes else "hulls/table"
            kind = f"{self._within[-1] if self._within else 'other'}: {target}, {'hand' if link is None else 'link'}"
            entry, asked = self.queries[kind], len(link) if isinstance(link, tuple) else 1  # several links: each
            entry[0], entry[1], entry[2] = entry[0] + asked, entry[1] + len(found), entry[2] + clock() - t
            return found
        return rows


@contextmanager
def staging(ledger: Ledger) -> Iterator[None]:
    """:data:`STAGES` and the simulator's closest-point queries reporting to ``ledger`` while inside."""
    import importlib

    from planner.sim import Sim

    saved = []
    for name, module, owner, attr in STAGES:
        holder = importlib.import_module(module)
        holder = getattr(holder, owner) if owner else holder
        if hasattr(holder, attr):  # a tree without the stage: not timed
            saved.append((holder, attr, getattr(holder, attr)))
            setattr(holder, attr, ledger.staged(name, getattr(holder, attr)))
    saved.append((Sim, "_rows", Sim._rows))
    Sim._rows = ledger.queried(Sim._rows)  # type: ignore[method-assign]
    try:
        yield
    finally:
        for holder, attr, fn in reversed(saved):
            setattr(holder, attr, fn)


@contextmanager
def instrumented(ledger: Ledger) -> Iterator[None]:
    """The unit module's candidate loop and pieces reporting to ``ledger`` while inside."""
    from planner.plan import keeping, measures, unit

    saved = {"_tried": unit._tried, "squeezed": keeping.squeezed, "measure": keeping.measure}
    resistances = measures.resistances

    def tried(todo, budget, result, report):  # type: ignore[no-untyped-def]
        for cand in saved["_tried"](todo, budget, result, report):
            ledger.begin(result)
            yield cand
        ledger.end(result)

    unit._tried = tried
    keeping.squeezed = ledger.timed("squeeze", saved["squeezed"])  # the keeper squeezes and measures (a unit's
    keeping.measure = ledger.timed("measure", saved["measure"])  # closed grasps and its squeezes' ends)
    measures.resistances = ledger.timed("resist", resistances)
    try:
        yield
    finally:
        unit._tried, keeping.squeezed, keeping.measure = saved["_tried"], saved["squeezed"], saved["measure"]
        measures.resistances = resistances


def profile_unit(obj: str, hand: str, approaches: int, stats: Path | None = None, mass: float | None = None,
                 friction: float | None = None) -> dict:
    """One object's figures (see the module docstring)."""
    from planner.geometry.proxy import collision_proxy
    from planner.geometry.solid import load_object
    from planner.plan.sweep import SweepSettings
    from planner.plan.unit import UnitSpec, run_unit
    from planner.specs.physical import Physical

    physical = Physical(mass=mass, friction=friction)
    prepared = load_object(obj, **physical.given())
    collision_proxy(prepared.mesh, prepared.mesh_hash)
    ledger = Ledger()
    profiler = cProfile.Profile() if stats else None
    with instrumented(ledger), staging(ledger):
        t0 = clock()
        if profiler:
            profiler.enable()
        r = run_unit(UnitSpec(obj, hand, SweepSettings(approaches=approaches, chunk=0, reach_placements=0), 0,
                              physical=physical))
        if profiler:
            profiler.disable()
        total = clock() - t0
    if profiler and stats:
        stats.mkdir(parents=True, exist_ok=True)
        profiler.dump_stats(str(stats / f"{Path(obj).stem}_{hand}.prof"))
    flags = [g.force_closure for g in r.grasps]
    return {"object": obj, "hand": hand, "error": r.error, "cpu_total": total, "candidates": r.candidates,
            "grasps": len(r.grasps), "fc": r.force_closure, "cpu": dict(ledger.cpu), "count": dict(ledger.count),
            "pieces": dict(ledger.pieces), "measure_fc": sum(t for t, f in zip(ledger.measure_calls, flags) if f),
            "measure_not_fc": sum(t for t, f in zip(ledger.measure_calls, flags) if not f),
            "timing": r.timing, "rejected": dict(r.rejected), "stages": dict(ledger.stages),
            "queries": {k: list(v) for k, v in ledger.queries.items()}}


def table(row: dict) -> str:
    """One object's figures as lines of text."""
    p = row["pieces"]
    lines = [f"{row['object']} ({row['hand']}): {row['cpu_total']:.2f} CPU s, {row['candidates']} candidates, "
             f"{row['grasps']} stored, {row['fc']} FC: {1000 * row['cpu_total'] / max(row['fc'], 1):.1f} ms per FC"
             + (f"; error: {row['error']}" if row.get("error") else "")]
    for key in sorted(row["cpu"], key=lambda k: -row["cpu"][k]):
        n, s = row["count"][key], row["cpu"][key]
        lines.append(f"  {key:20s} {n:6d} {s:8.3f} s {1000 * s / n:8.3f} ms each {100 * s / row['cpu_total']:5.1f}%")
    lines.append(f"  {'squeeze':20s} {'':6s} {p.get('squeeze', 0.0):8.3f} s (grasps not FC as planned) "
                 f"{100 * p.get('squeeze', 0.0) / row['cpu_total']:5.1f}%")
    lines.append(f"  {'measures':20s} {'':6s} {row['measure_fc']:8.3f} s FC, {row['measure_not_fc']:.3f} s not FC; "
                 f"resistances {p.get('resist', 0.0):.3f} s")
    per = max(row["fc"], 1)
    lines.append("  stages (CPU s, ms per FC grasp): " + ", ".join(
        f"{k} {v:.3f} ({1000 * v / per:.2f})" for k, v in sorted(row["stages"].items(), key=lambda kv: -kv[1])))
    for kind, (n, found, s) in sorted(row["queries"].items(), key=lambda kv: -kv[1][2]):
        lines.append(f"  query {kind:36s} {n:6d} x {found / n:7.1f} rows {s:7.3f} s {1000 * s / n:6.3f} ms each")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--hand", default="panda")
    parser.add_argument("--objects", nargs="+", default=list(DEFAULT_OBJECTS))
    parser.add_argument("--approaches", type=int, default=256, help="points (antipodal) or rays of the unit")
    parser.add_argument("--json-out", type=Path)
    parser.add_argument("--cprofile", type=Path, help="write each object's cProfile stats to this folder")
    parser.add_argument("--mass", type=float, help="[kg] every object's mass (default: its own)")
    parser.add_argument("--friction", type=float, help="every object's friction (default: its own)")
    args = parser.parse_args()
    rows = []
    for obj in args.objects:
        rows.append(profile_unit(obj, args.hand, args.approaches, args.cprofile, args.mass, args.friction))
        print(table(rows[-1]), flush=True)
    if args.json_out:
        args.json_out.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
