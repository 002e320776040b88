"""The database's reads of its units of work and of where objects came from (a part of
:class:`planner.db.store.Database`): which units are done, which grasps hold a run's results, when an object was
last swept, which names a file is stored under, a unit's grasps' ids."""

from __future__ import annotations

import json
import sqlite3
from collections import Counter
from datetime import datetime

from planner.db.failures import _reads


class UnitReads:
    """Reads of ``units`` and ``objects`` rows, mixed into :class:`~planner.db.store.Database`."""

    _conn: sqlite3.Connection

    @_reads
    def units_done(self, hand: str, settings_hash: str, seed: int) -> set[tuple[str, int]]:
        """(object, chunk) of every finished unit with these settings."""
        rows = self._conn.execute(
            "SELECT object, chunk FROM units WHERE hand = ? AND settings_hash = ? AND seed = ? AND status = 'done'",
            (hand, settings_hash, seed))
        return {(r["object"], r["chunk"]) for r in rows}

    @_reads
    def grasp_ids(self, unit_id: int) -> dict[tuple[int, bool], int]:
        """(candidate number, whether a squeeze's end) -> grasp id of one unit's grasps (its key)."""
        rows = self._conn.execute("SELECT candidate, squeezed_from_turn IS NOT NULL AS e, id FROM grasps WHERE "
                                  "unit_id = ?", (unit_id,))
        return {(r["candidate"], bool(r["e"])): r["id"] for r in rows}

    @_reads
    def hand_swept(self, hand: str) -> bool:
        """Whether any finished unit (a sweep or an import) stored ``hand``'s results."""
        return self._conn.execute("SELECT 1 FROM units WHERE hand = ? AND status = 'done' LIMIT 1",
                                  (hand,)).fetchone() is not None

    @_reads
    def swept_settings(self, obj: str, hand: str, seed: int) -> set[str]:
        """The settings (JSON, as stored) of ``obj``'s units for ``hand`` with ``seed``, finished or failed (a
        failed unit keeps the grasps it found before its error)."""
        rows = self._conn.execute("SELECT DISTINCT settings FROM units WHERE object = ? AND hand = ? AND seed = ?",
                                  (obj, hand, seed))
        return {r["settings"] for r in rows}

    @_reads
    def validated_ids(self, obj: str, hand: str, table: str, seed: int, settings: str) -> set[int]:
        """Ids of ``obj``'s grasps for ``hand`` with a row in ``table`` (``validation``: PyBullet's trial,
        ``mujoco``, ``robust``) made with ``seed`` and ``settings`` (as stored)."""
        if table not in ("validation", "mujoco", "robust"):
            raise ValueError(f"no validation table '{table}'")
        rows = self._conn.execute(f"SELECT v.grasp_id FROM {table} v JOIN grasps g ON g.id = v.grasp_id "
                                  "WHERE g.object = ? AND g.hand = ? AND v.seed = ? AND v.settings = ?",
                                  (obj, hand, seed, settings))
        return {int(r["grasp_id"]) for r in rows}

    @_reads
    def last_finished(self, obj: str) -> float | None:
        """When ``obj``'s last unit (any hand) finished [s since the epoch]; None: none has. Rows with an offset
        (UTC, since 2026-12-05) are exact anywhere; older ones are the writer's local time, read as this
        machine's."""
        rows = self._conn.execute("SELECT finished_at FROM units WHERE object = ? AND status = 'done'", (obj,))
        times = []
        for r in rows:
            try:
                times.append(datetime.fromisoformat(r["finished_at"]).timestamp())
            except (TypeError, ValueError):
                continue
        return max(times, default=None)

    @_reads
    def swept(self, obj: str, hand: str) -> tuple[int, int, Counter]:
        """(finished units, their candidates, their rejections by reason) of ``obj``'s sweeps for ``hand``."""
        rows = self._conn.execute("SELECT candidates, rejected FROM units WHERE object = ? AND hand = ? AND "
                                  "status = 'done'", (obj, hand)).fetchall()
        rejected: Counter = Counter()
        for r in rows:
            rejected.update(json.loads(r["rejected"] or "{}"))
        return len(rows), sum(int(r["candidates"] or 0) for r in rows), rejected

    @_reads
    def grasp_count(self, obj: str, hand: str) -> int:
        """How many grasps of ``obj`` for ``hand`` are stored (the ranks there are: 1 to this)."""
        return int(self._conn.execute("SELECT COUNT(*) FROM grasps WHERE object = ? AND hand = ? AND rank IS NOT NULL",
                                      (obj, hand)).fetchone()[0])

    @_reads
    def unit_file_labels(self, obj: str, hand: str, settings_hash: str, seed: int) -> dict[int, bool]:
        """Candidate -> whether it carries the label of the file it was imported from, of each grasp that the
        finished unit of ``obj`` for ``hand`` with these settings (an import: its file's digest) stored."""
        rows = self._conn.execute("SELECT g.candidate, MAX(fl.grasp_id IS NOT NULL) AS labelled FROM units u JOIN "
                                  "grasps g ON g.unit_id = u.id LEFT JOIN file_labels fl ON fl.grasp_id = g.id WHERE "
                                  "u.object = ? AND u.hand = ? AND u.settings_hash = ? AND u.seed = ? AND "
                                  "u.status = 'done' GROUP BY g.candidate", (obj, hand, settings_hash, seed))
        return {int(r["candidate"]): bool(r["labelled"]) for r in rows}

    @_reads
    def label_file_hashes(self) -> dict[int, str]:
        """Unit id -> the sha256 of the file whose own labels its grasps carry (``grasp import``'s, kept in each file
        label row's settings), for every unit with such grasps."""
        rows = self._conn.execute("SELECT g.unit_id, MIN(fl.settings) AS settings FROM file_labels fl JOIN grasps g "
                                  "ON g.id = fl.grasp_id GROUP BY g.unit_id")
        out = {}
        for r in rows:
            imported = json.loads(r["settings"] or "{}").get("imported", "{}")
            digest = (json.loads(imported) if isinstance(imported, str) else imported).get("sha256")
            if digest:
                out[int(r["unit_id"])] = str(digest)
        return out

    @_reads
    def untold_ups(self) -> dict[tuple[str, str], str]:
        """(object, hand) -> the up an import took its object standing on untold (its unit's settings' ``up_taken``:
        the file gave no object/up, nor --up, a sidecar or the registry), where it is still the object's stored up."""
        rows = self._conn.execute("SELECT DISTINCT u.object, u.hand, u.settings, o.up FROM units u JOIN objects o ON "
                                  "o.name = u.object WHERE u.status = 'done' AND u.settings LIKE '%\"up_taken\"%'")
        out = {}
        for r in rows:
            taken = json.loads(r["settings"]).get("up_taken")
            if taken is not None and taken == r["up"]:
                out[(r["object"], r["hand"])] = str(taken)
        return out

    @_reads
    def names_by_source(self) -> dict[tuple[str, float], list[str]]:
        """(source, scale) -> the names of the objects stored from that file at that scale."""
        out: dict[tuple[str, float], list[str]] = {}
        for r in self._conn.execute("SELECT name, source, scale FROM objects ORDER BY name"):
            out.setdefault((r["source"], float(r["scale"])), []).append(r["name"])
        return out
