"""Tests of the estimator and its pipeline (hystdisc.estimator, hystdisc.pipeline)."""
