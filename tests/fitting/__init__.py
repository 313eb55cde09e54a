"""Tests of stage 2 (hystdisc.fitting): the output-error fits, their Jacobians, several starts."""
