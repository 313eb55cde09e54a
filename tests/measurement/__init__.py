"""Tests of the measurement as the fits see it (hystdisc.measurement)."""
