"""Scenario schema, loading, --set overrides, path and ${VAR} expansion."""

from testbench.config.loader import LoadedScenario, load_scenario
from testbench.config.schema import Scenario

__all__ = ["LoadedScenario", "Scenario", "load_scenario"]
