"""Load a scenario: YAML -> `--set` overrides -> ${VAR} expansion -> schema validation ->
component params validation. Every user mistake becomes one InputError line naming the file,
the key path and what was expected.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pydantic
import yaml

from testbench.config.schema import Scenario
from testbench.core import registry
from testbench.core.errors import InputError

_VAR = re.compile(r"\$\{([A-Za-z_][A-Za-z0-9_]*)\}")
_NUMBER_WITH_UNIT = re.compile(r"^\s*[-+]?\d+(\.\d*)?([eE][-+]?\d+)?\s*[A-Za-z/%]+\s*$")
_UNIT_SUFFIXES = {
    "_m": "metres", "_s": "seconds", "_hz": "hertz", "_deg": "degrees", "_mps": "metres per second",
    "_rad": "radians", "_km": "kilometres", "_kg": "kilograms", "_mps2": "m/s^2", "_dbm": "dBm",
}
_MAP_KEYS = ("imagery", "reference_map", "elevation", "reference_elevation")


@dataclass(frozen=True)
class LoadedScenario:
    """A validated scenario, the resolved dict it came from, and where it came from."""

    scenario: Scenario
    data: dict[str, Any]
    path: Path

    @property
    def directory(self) -> Path:
        return self.path.parent


def load_scenario(path: str | os.PathLike, overrides: list[str] | tuple[str, ...] = ()) -> LoadedScenario:
    """Read, override, expand and validate a scenario file (see module docstring)."""
    p = Path(path)
    if not p.is_file():
        raise InputError(f"{p}: scenario file not found")
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise InputError(f"{p}: cannot read ({exc.strerror})") from None
    data = parse_yaml(text, str(p))
    for item in overrides:
        apply_override(data, item, str(p))
    data = expand_env(data, str(p))
    _resolve_map_paths(data, p.parent)
    scenario = validate(data, str(p))
    validate_components(scenario, str(p))
    return LoadedScenario(scenario=scenario, data=data, path=p.resolve())


def parse_yaml(text: str, where: str) -> dict[str, Any]:
    """YAML text -> mapping; syntax errors name the line and column (1-based)."""
    try:
        data = yaml.safe_load(text)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        loc = f"line {mark.line + 1}, column {mark.column + 1}" if mark else "unknown position"
        raise InputError(f"{where}: YAML syntax error at {loc}: {exc.problem or exc.context}") from None
    except yaml.YAMLError as exc:
        raise InputError(f"{where}: YAML error: {exc}") from None
    if not isinstance(data, dict):
        raise InputError(f"{where}: expected a mapping of scenario keys at the top level, got {type(data).__name__}")
    # Top-level keys starting with "x-" only hold YAML anchors shared by other blocks.
    data = {k: v for k, v in data.items() if not (isinstance(k, str) and k.startswith("x-"))}
    # Aliases (*anchor) share one object; unshare them so that --set changes one place only.
    return _unshared(data)


def _unshared(node: Any) -> Any:
    """A copy of a YAML tree in which no two places share a mutable object."""
    if isinstance(node, dict):
        return {k: _unshared(v) for k, v in node.items()}
    if isinstance(node, list):
        return [_unshared(v) for v in node]
    return node


def apply_override(data: dict[str, Any], item: str, where: str) -> None:
    """Apply one `key.path=value` override in place.

    Vehicles are addressed by id (`vehicles.uav0.initial.altitude_m=300`), sensors by name
    (`vehicles.uav0.sensors.imu.preset=tactical`); inside a component block a key other than
    type/params/name addresses its params (`vehicles.uav0.mission.altitude_m=300`). The value
    is parsed as YAML (numbers, booleans, lists). `key.path+=number` adds to the number the
    scenario has there (a Monte Carlo dispersion about the scenario's own value).
    """
    if "=" not in item:
        raise InputError(f"--set {item!r}: expected key.path=value")
    key, _, raw = item.partition("=")
    add = key.endswith("+")
    key = key[:-1] if add else key
    parts = [s for s in key.strip().split(".") if s]
    if not parts:
        raise InputError(f"--set {item!r}: empty key path")
    try:
        value = yaml.safe_load(raw) if raw.strip() else ""
    except yaml.YAMLError:
        value = raw
    node: Any = data
    walked: list[str] = []
    for i, part in enumerate(parts):
        last = i == len(parts) - 1
        if isinstance(node, list):
            idx = _list_index(node, part)
            if idx is None:
                names = [_item_name(x) for x in node]
                raise InputError(f"--set {key}: no item {part!r} in {'.'.join(walked) or 'top level'} (have: {', '.join(map(str, names))})")
            if last:
                node[idx] = _added(node[idx], value, key) if add else value
                return
            node = node[idx]
        elif isinstance(node, dict):
            if "type" in node and part not in ("type", "params", "name"):
                node = node.setdefault("params", {})
                if not isinstance(node, dict):
                    raise InputError(f"--set {key}: params of {'.'.join(walked)} is not a mapping")
            if last:
                node[part] = _added(node.get(part), value, key) if add else value
                return
            if part not in node or node[part] is None:
                node[part] = {}
            node = node[part]
        else:
            raise InputError(f"--set {key}: {'.'.join(walked)} is a value, not a mapping or list")
        walked.append(part)


def _added(current: Any, value: Any, key: str) -> float:
    """current + value for a `key+=value` override; both must be numbers."""
    def number(x: Any) -> bool:
        return isinstance(x, (int, float)) and not isinstance(x, bool)

    if current is None:
        raise InputError(f"--set {key}+=...: the scenario has no value at {key} to add to; use {key}=value")
    if not number(current) or not number(value):
        raise InputError(f"--set {key}+={value!r}: adds numbers only (the scenario has {current!r} there)")
    return current + value


def _item_name(item: Any) -> Any:
    if isinstance(item, dict):
        return item.get("id") or item.get("name") or item.get("type")
    return item


def _list_index(items: list[Any], part: str) -> int | None:
    for i, item in enumerate(items):
        if isinstance(item, dict) and part in (item.get("id"), item.get("name")):
            return i
    for i, item in enumerate(items):  # sensors without a name are addressed by type
        if isinstance(item, dict) and item.get("name") is None and item.get("type") == part:
            return i
    if part.lstrip("-").isdigit() and -len(items) <= int(part) < len(items):
        return int(part)
    return None


def expand_env(node: Any, where: str, path: str = "") -> Any:
    """Replace ${VAR} in every string with the environment's value; an unset variable is an error."""
    if isinstance(node, dict):
        return {k: expand_env(v, where, f"{path}.{k}" if path else str(k)) for k, v in node.items()}
    if isinstance(node, list):
        return [expand_env(v, where, f"{path}[{i}]") for i, v in enumerate(node)]
    if isinstance(node, str):
        def sub(m: re.Match[str]) -> str:
            name = m.group(1)
            if name not in os.environ:
                raise InputError(f"{where}: {path}: environment variable ${{{name}}} is not set (needed for {node!r})")
            return os.environ[name]
        return _VAR.sub(sub, node)
    return node


def _is_map_path(key: str, value: Any) -> bool:
    """True when world.<key>'s value names a file: not a `procedural:` world, and for the
    elevation keys not flat ground ('flat' or 'flat:HEIGHT_M', world.spec.open_elevation)."""
    if not isinstance(value, str) or not value or value.strip().startswith("procedural:"):
        return False
    flat = value.strip().lower()
    return not (key.endswith("elevation") and (flat == "flat" or flat.startswith("flat:")))


def _resolve_map_paths(data: dict[str, Any], base: Path) -> None:
    """Make world map paths absolute, relative to the scenario's folder."""
    world = data.get("world")
    if not isinstance(world, dict):
        return
    for k in _MAP_KEYS:
        v = world.get(k)
        if _is_map_path(k, v) and not os.path.isabs(v):
            world[k] = str((base / v).resolve())


def _loc_text(loc: tuple[Any, ...], data: dict[str, Any]) -> str:
    """Pydantic location -> dotted path, naming vehicles by id and sensors by name."""
    out: list[str] = []
    node: Any = data
    for part in loc:
        if isinstance(part, int) and isinstance(node, list) and 0 <= part < len(node):
            name = _item_name(node[part])
            out.append(f"[{name}]" if name is not None else f"[{part}]")
            node = node[part]
        else:
            out.append(("." if out else "") + str(part))
            node = node.get(part) if isinstance(node, dict) else None
    return "".join(out)


def _unit_hint(key: str, value: Any) -> str:
    if isinstance(value, str) and _NUMBER_WITH_UNIT.match(value):
        for suffix, unit in _UNIT_SUFFIXES.items():
            if key.endswith(suffix):
                return f"; write a plain number in {unit} (the key's suffix {suffix} gives the unit)"
        return "; write a plain number (units are given by the key name)"
    return ""


def validate(data: dict[str, Any], where: str) -> Scenario:
    """Validate the resolved dict against the schema; one line per the first error."""
    try:
        return Scenario.model_validate(data)
    except pydantic.ValidationError as exc:
        err = exc.errors()[0]
        loc = _loc_text(tuple(err["loc"]), data)
        key = str(err["loc"][-1]) if err["loc"] else ""
        if err["type"] == "extra_forbidden":
            raise InputError(f"{where}: {loc}: unknown key") from None
        if err["type"] == "missing":
            raise InputError(f"{where}: {loc}: missing required key") from None
        got = err.get("input")
        got_txt = "" if isinstance(got, (dict, list)) else f" (got {got!r})"
        raise InputError(f"{where}: {loc}: {err['msg']}{got_txt}{_unit_hint(key, got)}") from None


def validate_components(scenario: Scenario, where: str) -> None:
    """Resolve every component's class and validate its params against the class's model."""
    for v in scenario.vehicles:
        base = f"{where}: vehicles[{v.id}]"
        for s in v.sensors:
            cls = registry.resolve_class("sensor", s.type, where=f"{base}.sensors[{s.sensor_name}].type")
            registry.validate_params(cls, s.params, where=f"{base}.sensors[{s.sensor_name}].params")
        for i, aid in enumerate(v.aids):
            cls = registry.resolve_class("aid", aid.type, where=f"{base}.aids[{i}].type")
            registry.validate_params(cls, aid.params, where=f"{base}.aids[{i}].params")
        for kind, spec, label in (
            ("navigator", v.navigation, "navigation"),
            ("controller", v.control, "control"),
            ("mission", v.mission, "mission"),
        ):
            if spec is None:
                continue
            cls = registry.resolve_class(kind, spec.type, where=f"{base}.{label}.type")
            registry.validate_params(cls, spec.params, where=f"{base}.{label}.params")
