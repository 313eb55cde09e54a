"""Simulation: compiled integrators for every model and experiment, and synthetic data."""
