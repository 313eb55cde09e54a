"""Plotting functions: each takes ``ax=`` and returns its artists."""
