"""Tests of stage 1 (hystdisc.discovery): the library, the shapes, the sparse regression."""
