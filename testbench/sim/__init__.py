"""Simulation: vehicle assembly, the multi-rate engine, the recorder, the run orchestration.

`sim` is the only orchestrator: it builds components from the scenario and wires the data
flow world -> dynamics -> sensors -> navigation -> control -> dynamics.
"""
