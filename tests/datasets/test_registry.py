"""The format registry: every format registers what it claims, a bad
registration fails when it is made, unknown names list the valid ones."""

from __future__ import annotations

import inspect
from pathlib import Path

import pytest

from planner import api
from planner.datasets import formats, registry
from planner.datasets.registry import PairWriter, Reader, RegistrationError, TableWriter
from planner.errors import UnknownNameError

#: What each format claims: its writer's kind, and whether ``grasp import`` reads it.
CLAIMS = {"acronym": (PairWriter, True), "graspgen": (PairWriter, False), "dexgraspnet": (PairWriter, False),
          "moveit": (PairWriter, False), "parquet": (TableWriter, False), "csv": (TableWriter, False)}


def _write(path, obj, hand, batches):  # type: ignore[no-untyped-def]
    return 0


def _path(stem, hand):  # type: ignore[no-untyped-def]
    return f"{stem}__{hand}.x"


def test_every_format_has_the_writer_and_reader_it_claims() -> None:
    assert {m.__name__ for m in formats.MODULES} == {f"planner.datasets.{m}" for m in
                                                    ("acronym", "graspgen", "dexgraspnet", "moveit", "table")}
    assert set(registry.export_formats()) == set(CLAIMS) == set(api.EXPORT_FORMATS)
    assert registry.import_formats() == tuple(n for n, (_, reads) in CLAIMS.items() if reads) == api.IMPORT_FORMATS
    for name, (kind, reads) in CLAIMS.items():
        writer = registry.writer(name)
        assert isinstance(writer, kind), name
        if isinstance(writer, PairWriter):
            assert list(inspect.signature(writer.write).parameters) == ["path", "info", "hand", "batches"], name
            where = writer.relative_path("box", "panda")
            assert "box" in where and "panda" in where and not where.startswith("/"), name
        else:
            assert list(inspect.signature(writer.write).parameters) == ["path", "streams"], name
            assert writer.file.startswith("grasps.") and writer.file.endswith(name), name
        if reads:
            reader = registry.reader(name)
            assert reader.poses.__module__ == writer.write.__module__, "reader and writer live side by side"
        else:
            with pytest.raises(UnknownNameError, match="Available import formats: acronym$"):
                registry.reader(name)


def test_the_exporter_meets_each_hook_the_formats_register() -> None:
    graspgen, dexgraspnet = registry.writer("graspgen"), registry.writer("dexgraspnet")
    assert isinstance(graspgen, PairWriter) and graspgen.finish is not None
    assert isinstance(dexgraspnet, PairWriter) and dexgraspnet.mesh_copies == ("meshdata/{stem}/coacd/decomposed.obj",)


@pytest.mark.parametrize("bad, message", [
    (lambda: PairWriter(_path, "write"), "PairWriter.write must be a function"),
    (lambda: PairWriter(_path, lambda path, obj: 0), "PairWriter.write must take 4 positional arguments"),
    (lambda: PairWriter(_path, _write, finish=lambda out: None), "PairWriter.finish must take 2"),
    (lambda: PairWriter(_path, _write, mesh_copies=("meshes/copy.obj",)), "must be a path with '{stem}'"),
    (lambda: TableWriter("out/grasps.x", lambda path, streams: 0), "must be a file name"),
    (lambda: TableWriter("grasps.x", lambda path, streams: 0, notes=lambda: []), "TableWriter.notes must take 1"),
    (lambda: Reader(print, None, print, print), "Reader.poses must be a function"),  # type: ignore[arg-type]
    (lambda: registry.register("acronym", PairWriter(_path, _write)), "format 'acronym' is registered twice"),
    (lambda: registry.register("Bad-Name", PairWriter(_path, _write)), "must be lower case"),
    (lambda: registry.register("nothing"), "neither a writer nor a reader"),
    (lambda: registry.register("loose", writer=_write), "writer must be a PairWriter or TableWriter"),  # type: ignore[arg-type]
])
def test_a_bad_registration_fails_loudly_and_registers_nothing(bad, message: str) -> None:  # type: ignore[no-untyped-def]
    before = registry.export_formats(), registry.import_formats()
    with pytest.raises(RegistrationError, match=message.replace("(", r"\(")):
        bad()
    assert (registry.export_formats(), registry.import_formats()) == before


def test_an_unknown_format_lists_the_registered_ones(tmp_path: Path) -> None:
    listed = "Available formats: acronym, csv, dexgraspnet, graspgen, moveit, parquet"
    with pytest.raises(UnknownNameError, match=listed):
        api.export(tmp_path / "g.db", "acronyn", tmp_path / "out")
