"""Flight dynamics: the JSBSim adapter, the aircraft catalogue, trim and linearisation."""
