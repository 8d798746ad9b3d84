"""Where aircraft models live: the project's own JSBSim root (`aircraft/`) and the models
bundled with the jsbsim package, plus each project model's testbench sidecar
(`aircraft/<name>/testbench.yaml`: kind, mass, cruise speed, rotor geometry ...).
"""

from __future__ import annotations

import functools
import os
from pathlib import Path

import jsbsim
import yaml

from testbench.core.errors import InputError

PROJECT_AIRCRAFT_DIR = Path(__file__).resolve().parents[2] / "aircraft"
"""The project's JSBSim aircraft folder (<repo>/aircraft)."""


def _bundled_aircraft_dir() -> Path:
    return Path(jsbsim.get_default_root_dir()) / "aircraft"


def _models_in(folder: Path) -> list[str]:
    if not folder.is_dir():
        return []
    return sorted(p.name for p in folder.iterdir() if (p / f"{p.name}.xml").is_file())


def project_aircraft() -> list[str]:
    """Names of the project's own models."""
    return _models_in(PROJECT_AIRCRAFT_DIR)


def bundled_aircraft() -> list[str]:
    """Names of the models shipped with the jsbsim package."""
    return _models_in(_bundled_aircraft_dir())


def available_aircraft() -> list[str]:
    """Every model name usable in a scenario (project models first)."""
    own = project_aircraft()
    return own + [n for n in bundled_aircraft() if n not in own]


def aircraft_dir(name: str) -> Path:
    """Folder that holds <name>/<name>.xml (the JSBSim aircraft path to load it from).

    Raises InputError listing the available models when the name is unknown.
    """
    for folder in (PROJECT_AIRCRAFT_DIR, _bundled_aircraft_dir()):
        if (folder / name / f"{name}.xml").is_file():
            return folder
    raise InputError(
        f"unknown aircraft {name!r}; available: {', '.join(available_aircraft())}"
    )


@functools.lru_cache(maxsize=None)
def _sidecar(name: str, mtime: float) -> dict:
    path = aircraft_dir(name) / name / "testbench.yaml"
    with open(path, encoding="utf-8") as fh:
        return yaml.safe_load(fh) or {}


def aircraft_meta(name: str) -> dict:
    """The model's testbench sidecar as a dict; bundled models without one are fixed-wing."""
    path = aircraft_dir(name) / name / "testbench.yaml"
    if not path.is_file():
        return {"kind": "fixed_wing", "name": name}
    meta = dict(_sidecar(name, os.path.getmtime(path)))
    meta.setdefault("name", name)
    return meta
