"""The families: one module each, registered in :mod:`hystdisc.registry`."""
