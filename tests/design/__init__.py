"""Tests of experiment design (hystdisc.design)."""
