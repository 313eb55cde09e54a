"""Tests of the models layer (hystdisc.models): parameters, families, effects, systems."""
