"""Experiment types: release, driven and forced, as objects that say what is measured."""
