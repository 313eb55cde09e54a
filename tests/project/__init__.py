"""Tests of the repository: the house rules, the documentation, the notebooks, the README."""
