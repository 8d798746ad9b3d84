"""Registry of swappable components, resolved from a scenario's `{type, params}` blocks.

A component class declares a pydantic `Params` model (extra keys forbidden) and is registered
under a kind ("sensor", "navigator", "controller", "matcher", "detector", "mission", ...) and a
name. A scenario names it by that name, or by "package.module:Class" for a user's own class.
`build()` validates the params against the class's model and constructs
`cls(params, **context)`; errors name the key path and what was expected.
"""

from __future__ import annotations

import importlib
from typing import Any, Callable

import pydantic

from testbench.core.errors import InputError

_REGISTRY: dict[str, dict[str, type]] = {}

# Importing these packages registers the built-in components of each kind.
_BUILTIN_PACKAGES: dict[str, tuple[str, ...]] = {
    "sensor": ("testbench.sensors",),
    "navigator": ("testbench.navigation",),
    "controller": ("testbench.control",),
    "mission": ("testbench.control",),
    "matcher": ("testbench.navigation.ismn",),
    "detector": ("testbench.navigation.relative",),
    "relative_estimator": ("testbench.navigation.relative",),
    "aid": ("testbench.navigation",),
}


def register(kind: str, name: str) -> Callable[[type], type]:
    """Class decorator: register `cls` as component `name` of `kind`."""

    def deco(cls: type) -> type:
        table = _REGISTRY.setdefault(kind, {})
        if name in table and table[name] is not cls:
            raise ValueError(f"{kind} {name!r} registered twice ({table[name]} and {cls})")
        table[name] = cls
        cls.registered_name = name
        return cls

    return deco


def _load_builtins(kind: str) -> None:
    for pkg in _BUILTIN_PACKAGES.get(kind, ()):
        importlib.import_module(pkg)


def available(kind: str) -> list[str]:
    """Sorted names of the registered components of `kind`."""
    _load_builtins(kind)
    return sorted(_REGISTRY.get(kind, {}))


def resolve_class(kind: str, type_name: str, where: str = "type") -> type:
    """The class named by a registry name or "package.module:Class"."""
    if ":" in type_name:
        module_name, _, attr = type_name.partition(":")
        try:
            module = importlib.import_module(module_name)
        except ImportError as exc:
            raise InputError(f"{where}: cannot import module {module_name!r} ({exc})") from None
        try:
            return getattr(module, attr)
        except AttributeError:
            raise InputError(f"{where}: module {module_name!r} has no attribute {attr!r}") from None
    _load_builtins(kind)
    table = _REGISTRY.get(kind, {})
    if type_name not in table:
        names = ", ".join(sorted(table)) or "none"
        raise InputError(
            f"{where}: unknown {kind} type {type_name!r}; expected one of: {names}, "
            "or 'package.module:Class'"
        )
    return table[type_name]


def format_validation_error(exc: pydantic.ValidationError, where: str) -> str:
    """One line naming the first offending key path and what was expected."""
    err = exc.errors()[0]
    loc = ".".join(str(p) for p in err["loc"])
    path = f"{where}.{loc}" if loc else where
    if err["type"] == "extra_forbidden":
        return f"{path}: unknown key"
    if err["type"] == "missing":
        return f"{path}: missing required key"
    got = err.get("input")
    got_txt = "" if isinstance(got, dict) else f" (got {got!r})"
    return f"{path}: {err['msg']}{got_txt}"


def validate_params(cls: type, params: dict[str, Any] | None, where: str) -> Any:
    """Validate `params` against `cls.Params`; returns the model instance."""
    model = getattr(cls, "Params", None)
    if model is None:
        if params:
            raise InputError(f"{where}: {cls.__name__} takes no params")
        return None
    try:
        return model.model_validate(params or {})
    except pydantic.ValidationError as exc:
        raise InputError(format_validation_error(exc, where)) from None


def build(kind: str, type_name: str, params: dict[str, Any] | None, where: str, **context: Any) -> Any:
    """Resolve, validate and construct one component: `cls(validated_params, **context)`."""
    cls = resolve_class(kind, type_name, where=f"{where}.type")
    p = validate_params(cls, params, where=f"{where}.params")
    return cls(p, **context)


class ParamsModel(pydantic.BaseModel):
    """Base of every component's `Params`: unknown keys are errors, values are frozen."""

    model_config = pydantic.ConfigDict(extra="forbid", frozen=True)
