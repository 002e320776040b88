"""``key=value`` changes to a frozen settings dataclass, as the benchmarks' ``--set`` options take them."""

from __future__ import annotations

import sys
from dataclasses import fields


def parse(pairs: list[str], cls: type, tool: str) -> dict:
    """{field: typed value} of ``pairs`` (``key=value``) for the dataclass ``cls``; ``none`` switches an optional
    field off. An unknown key exits with a one-line error naming ``tool`` and the settings it has."""
    kinds = {f.name: f.type for f in fields(cls)}
    out: dict = {}
    for kv in pairs:
        key, _, value = kv.partition("=")
        if key not in kinds:
            sys.exit(f"{tool}: unknown setting {key}; settings: {', '.join(kinds)}")
        kind = kinds[key]
        if value.lower() == "none" and "None" in str(kind):  # an optional setting switched off (friction_cap)
            out[key] = None
            continue
        kind = str(kind).split(" | ")[0]  # an optional setting's own type (islands: bool | None)
        out[key] = value if kind == "str" else (value.lower() in ("1", "true", "yes")) if kind == "bool" \
            else int(value) if kind == "int" else float(value)
    return out
