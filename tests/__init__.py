"""The test suite: one folder per layer of hystdisc (doc/develop.rst, "Tests")."""
