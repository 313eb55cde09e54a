"""Tests of the applying layer (hystdisc.apply): predictions and the python-control export."""
