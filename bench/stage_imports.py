"""The import arrows between the planner's stages (its sub-packages and
top-level modules): ``python bench/stage_imports.py`` prints one line per
stage, ``stage -> the stages it imports`` (type-only imports included), and
the pairs of stages that import each other. Parses the source (``ast``); runs nothing."""

from __future__ import annotations

import ast
import sys
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent / "planner"


def stage_of(module: str) -> str | None:
    """``planner.db.store`` -> ``db``; ``planner.api`` -> ``api``; other packages -> None."""
    parts = module.split(".")
    return parts[1] if parts[0] == "planner" and len(parts) > 1 else None


def arrows(root: Path = ROOT) -> dict[str, set[str]]:
    """stage -> the other stages its modules import."""
    out: dict[str, set[str]] = defaultdict(set)
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root.parent).with_suffix("")
        here = stage_of(".".join(rel.parts))
        if here is None or here == "__init__":
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module or ""] if isinstance(node, ast.ImportFrom) and node.level == 0 else []
            if isinstance(node, ast.ImportFrom) and node.module == "planner":
                names = [f"planner.{a.name}" for a in node.names]
            for name in names:
                there = stage_of(name)
                if there is not None and there != here:
                    out[here].add(there)
        out.setdefault(here, set())
    return dict(out)


def main() -> None:
    found = arrows(Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT)
    for stage in sorted(found):
        print(f"{stage} -> {', '.join(sorted(found[stage])) or '(none)'}")
    both = sorted({tuple(sorted((a, b))) for a, targets in found.items() for b in targets if a in found.get(b, ())})
    print("both ways: " + (", ".join(f"{a} <-> {b}" for a, b in both) or "(none)"))


if __name__ == "__main__":
    main()
