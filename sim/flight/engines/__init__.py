"""Simulation engines: the plain-numpy reference step and the fused numba kernel."""
