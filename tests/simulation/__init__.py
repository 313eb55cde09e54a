"""Tests of the simulation layer (hystdisc.simulation)."""
