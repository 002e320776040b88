"""One exception root for the project.

Every error a user can trigger is a :class:`PlannerError` subclass whose
message names the input and says what to fix.  The CLI maps each subclass to
an exit code and prints the message on one line; ``--debug`` shows the
traceback.
"""

from __future__ import annotations

from collections.abc import Iterable


class PlannerError(Exception):
    """Root of every error the planner raises on purpose."""

    exit_code = 1

    def __str__(self) -> str:
        """The message on one line: control characters of quoted user input
        (a line break in a TOML string) are shown escaped."""
        text = super().__str__()
        return text if text.isprintable() else "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


class InputError(PlannerError):
    """Bad user input: a missing or broken file, an unknown name, bad values."""

    exit_code = 2


class UnknownNameError(InputError):
    """A name that is not in a registry; the message lists the valid ones."""

    def __init__(self, kind: str, name: str, available: Iterable[str]) -> None:
        names = ", ".join(sorted(available)) or "(none)"
        super().__init__(f"unknown {kind} '{name}'. Available {kind}s: {names}")
        self.kind = kind
        self.name = name


class ConfigError(InputError):
    """A TOML or URDF description that is malformed or inconsistent."""


class MeshError(InputError):
    """A mesh that cannot be used: empty, non-finite, flat, wrong units..."""


class DegenerateGraspError(InputError):
    """Contacts that cannot be analysed (bad shapes, NaNs, zero normals)."""


class NotFoundError(PlannerError):
    """A query that ran and found nothing (no reachable grasp): exit code 1."""

    exit_code = 1


class DatabaseError(PlannerError):
    """The database cannot be opened, read or written safely."""

    exit_code = 3


class SimulationError(PlannerError):
    """The physics backend failed in a way that is not the user's input."""

    exit_code = 4
