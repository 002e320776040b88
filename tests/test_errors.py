"""One exception root; exit codes by kind; unknown names list the valid ones."""

from __future__ import annotations

from planner.errors import (
    ConfigError,
    DatabaseError,
    InputError,
    MeshError,
    PlannerError,
    SimulationError,
    UnknownNameError,
)


def test_exit_codes_by_kind() -> None:
    assert PlannerError.exit_code == 1
    assert InputError.exit_code == ConfigError.exit_code == MeshError.exit_code == 2
    assert DatabaseError.exit_code == 3 and SimulationError.exit_code == 4
    assert all(issubclass(e, PlannerError) for e in (InputError, DatabaseError, SimulationError))


def test_unknown_names_are_listed_sorted() -> None:
    err = UnknownNameError("hand", "shadow", ["pr2", "panda"])
    assert str(err) == "unknown hand 'shadow'. Available hands: panda, pr2"
    assert isinstance(err, InputError) and (err.kind, err.name) == ("hand", "shadow")
    assert "(none)" in str(UnknownNameError("format", "x", []))
