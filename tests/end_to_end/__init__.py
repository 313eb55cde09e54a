"""Tests across the layers: faults, files, fuzzed inputs' corpus, the stress suites, measured data."""
