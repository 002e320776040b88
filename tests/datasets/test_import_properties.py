"""Import of a file that gives no object/mass or object/friction: the values taken are said, or a user's given."""

from __future__ import annotations

import logging
import sqlite3
from pathlib import Path

import h5py
import pytest
from helpers import grasp, one_line_error

from tests.datasets.test_importer import foreign_file


def _without(path: Path, *keys: str) -> Path:
    with h5py.File(path, "r+") as f:
        for key in keys:
            del f[f"object/{key}"]
    return path


def _stored(db: Path) -> tuple[float, float]:
    with sqlite3.connect(db) as conn:
        return conn.execute("SELECT mass, friction FROM objects").fetchone()


def test_a_file_without_mass_says_the_mass_taken_or_takes_the_users(db: Path, tmp_path: Path) -> None:
    """A file without object/mass was taken at 0.2 kg without a word; then the word was said again for the file
    skipped as imported before, which nothing measures again."""
    foreign, _ = foreign_file(db, tmp_path, "box", "crate")
    friction = h5py.File(foreign, "r")["object/friction"][()]
    _without(foreign, "mass")
    code, _, err = grasp("import", str(foreign), "--db", str(tmp_path / "a.db"))
    assert code == 0, err
    said = [line for line in err.splitlines() if "object/mass" in line]
    assert len(said) == 1 and "crate.h5: no object/mass" in said[0] and "0.2 kg (the default)" in said[0] \
        and "--mass" in said[0], err
    assert _stored(tmp_path / "a.db") == (0.2, friction)
    code, out, err = grasp("import", str(foreign), "--db", str(tmp_path / "a.db"))  # again: skipped, not measured
    assert code == 0 and "already imported" in out and "object/mass" not in err, err
    code, _, err = grasp("import", str(foreign), "--db", str(tmp_path / "b.db"), "--mass", "0.05")
    assert code == 0 and "object/mass" not in err, err
    assert _stored(tmp_path / "b.db") == (0.05, friction)


def test_a_file_without_friction_says_it_and_a_files_own_mass_is_not_replaced(db: Path, tmp_path: Path) -> None:
    foreign, _ = foreign_file(db, tmp_path, "box", "crate")
    mass = float(h5py.File(foreign, "r")["object/mass"][()])
    code, _, err = grasp("import", str(foreign), "--db", str(tmp_path / "a.db"), "--mass", str(mass * 2))
    one_line_error(code, err, 2, f"its object/mass is {mass:g}, and --mass gives {mass * 2:g}",
                   "leave --mass out for this file")
    assert not (tmp_path / "a.db").exists()
    _without(foreign, "friction")
    code, _, err = grasp("import", str(foreign), "--db", str(tmp_path / "b.db"), "--friction", "0.8")
    assert code == 0 and "object/friction" not in err, err
    assert _stored(tmp_path / "b.db") == (mass, 0.8)


def test_one_mass_for_a_command_of_several_files_is_said_so_in_its_help_and_its_error(db: Path,
                                                                                     tmp_path: Path) -> None:
    """Two files, one with its own object/mass and one without: `--mass` for the second was refused for the first,
    "leave --mass out for this file", which a command of both cannot; its help said "the objects' mass"."""
    import shutil

    foreign, _ = foreign_file(db, tmp_path, "box", "crate")
    bare = _without(Path(shutil.copy(foreign, foreign.with_name("bare.h5"))), "mass")
    mass = float(h5py.File(foreign, "r")["object/mass"][()])
    code, _, err = grasp("import", str(foreign), str(bare), "--db", str(tmp_path / "a.db"), "--mass", str(mass * 2))
    one_line_error(code, err, 2, "crate.h5: its object/mass", "leave --mass out for this file (--mass is one value "
                   "for every file of the command: give it in a command of the files without object/mass)")
    assert not (tmp_path / "a.db").exists()
    code, out, _ = grasp("import", "--help")
    assert code == 0 and "One mass [kg] for the object of every file of the command that gives none" in \
        " ".join(out.split())


def test_calibrate_says_the_mass_it_takes_for_a_file_without_one(db: Path, tmp_path: Path,
                                                                 caplog: pytest.LogCaptureFixture) -> None:
    """`grasp calibrate` reads each file as `import --rescore` does (importer.read_for_rescoring): once, with its
    note (it has no --mass: the file is to say it); read again to check the objects, without."""
    from planner.datasets.importer import read_for_rescoring

    foreign = _without(foreign_file(db, tmp_path, "box", "crate")[0], "mass")
    with caplog.at_level(logging.INFO, logger="planner.prepare"):
        read_for_rescoring(foreign, note=True)
        read_for_rescoring(foreign)
    said = [r.getMessage() for r in caplog.records if "object/mass" in r.getMessage()]
    assert len(said) == 1 and "0.2 kg (the default)" in said[0] and "set object/mass in the file" in said[0], said


@pytest.mark.parametrize(("option", "value", "said"), [("--mass", "-1", "--mass must be a positive number [kg]"),
                                                        ("--mass", "nan", "--mass must be a positive number [kg]"),
                                                        ("--friction", "5", "--friction must lie in (0, 3]")])
def test_a_bad_mass_or_friction_is_refused_as_the_option_given(db: Path, tmp_path: Path, option: str, value: str,
                                                                said: str) -> None:
    """A bad --mass was refused as the object's ("object '.../crate.obj': mass must be ..."), not as the option the
    user typed."""
    foreign = _without(foreign_file(db, tmp_path, "box", "crate")[0], "mass", "friction")
    code, _, err = grasp("import", str(foreign), "--db", str(tmp_path / "a.db"), option, value)
    one_line_error(code, err, 2, said, f"got {float(value)}")
    assert not (tmp_path / "a.db").exists()


def test_a_file_without_up_says_the_up_taken_and_how_to_choose_it(db: Path, tmp_path: Path) -> None:
    """A file without object/up (every ACRONYM file) was imported standing on +z without a word, though ACRONYM's
    meshes stand on +y: its com_height, gravity_arm and p_hold read the up."""
    foreign, _ = foreign_file(db, tmp_path, "box", "crate")
    code, _, err = grasp("import", str(foreign), "--db", str(tmp_path / "a.db"))
    assert code == 0, err
    said = [line for line in err.splitlines() if "object/up" in line]
    assert len(said) == 1 and "crate.h5: no object/up" in said[0] and "standing on +z" in said[0] \
        and "--up" in said[0] and "+y" in said[0], err
    code, _, err = grasp("import", str(foreign), "--db", str(tmp_path / "b.db"), "--up", "+y")
    assert code == 0 and "object/up" not in err, err
    with sqlite3.connect(tmp_path / "b.db") as conn:
        assert conn.execute("SELECT up FROM objects").fetchone()[0] == "+y"
    (tmp_path / "foreign" / "meshes" / "crate.toml").write_text('up = "+x"\n')  # the mesh's sidecar tells it
    code, _, err = grasp("import", str(foreign), "--db", str(tmp_path / "c.db"))
    assert code == 0 and "object/up" not in err, err
