"""What ``grasp import`` records of a file (:class:`ImportSettings`, its unit's settings) and says of it
(:class:`ImportResult`); the import itself is :mod:`planner.datasets.importer`."""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

#: Bumped when an import of the same file would store different grasps.
IMPORT_VERSION = 1


@dataclass(frozen=True)
class ImportSettings:
    """The settings of an import unit (the ``units`` row's settings and hash)."""

    format: str
    file: str
    sha256: str
    rescore: bool
    #: the up the object was taken standing on untold (the file gives no object/up, nor did --up, a sidecar or
    #: the registry): ``grasp validate`` says it; None where told. Not part of :attr:`digest`
    up_taken: str | None = None

    def to_json(self) -> str:
        taken = {} if self.up_taken is None else {"up_taken": self.up_taken}
        return json.dumps({"import": self.format, "file": self.file, "sha256": self.sha256,
                           "rescore": self.rescore, "import_version": IMPORT_VERSION, **taken}, sort_keys=True)

    @property
    def digest(self) -> str:
        """Content, not path: the same file imported from elsewhere is the same unit."""
        key = json.dumps([self.format, self.sha256, self.rescore, IMPORT_VERSION])
        return hashlib.sha256(key.encode()).hexdigest()[:16]


@dataclass(frozen=True)
class ImportResult:
    path: Path
    object: str
    hand: str
    grasps: int
    force_closure: int
    rescored: bool
    skipped: bool  # already imported: nothing written
    rejected: dict[str, int]
    error: str | None = None  # re-scoring failed: stored as a failed unit, retried by the next import
    labels: tuple[int, int] = (0, 0)  # the grasps stored with their file's label: (held, dropped)
    #: a skipped file's stored grasps whose file row has a label the database holds none of (imported before it
    #: kept a file's labels, v16)
    unstored_labels: int = 0
    #: the file of the command this one is the same unit as (its bytes, object and hand: ``a.h5 ./a.h5``), where
    #: it was imported (or skipped) once: nothing of this one is read again
    same_as: Path | None = None

    def to_json(self) -> dict:
        return {**self.__dict__, "path": str(self.path), "same_as": None if self.same_as is None else str(self.same_as)}
