"""GNSS-denied navigation testbench for UAVs and UAV swarms.

See README.md for the command line and DESIGN.md (shared) for the architecture.
"""

__version__ = "0.1.0"
