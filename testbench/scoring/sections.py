"""The nested dicts of result dataclasses: what metrics.json and the batch tables are made of.
Fields that are None (no data for them in the run) are left out, so an absent capability
leaves no key behind."""

from __future__ import annotations

import dataclasses
from typing import Any, Mapping


def _convert(value: Any) -> Any:
    if hasattr(value, "to_dict"):
        return value.to_dict()
    if isinstance(value, Mapping):
        return {str(k): _convert(v) for k, v in value.items() if v is not None}
    return value


def section_dict(obj: Any) -> dict[str, Any]:
    """Nested dict of a result dataclass: None fields dropped, children converted."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(obj):
        v = getattr(obj, f.name)
        if v is None:
            continue
        v = _convert(v)
        if isinstance(v, dict) and not v:
            continue
        out[f.name] = v
    return out


class Section:
    """A result dataclass: to_dict() gives its nested dict (section_dict)."""

    def to_dict(self) -> dict[str, Any]:
        return section_dict(self)
