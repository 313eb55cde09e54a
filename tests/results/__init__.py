"""Tests of the typed, versioned results (hystdisc.results)."""
