"""Tests of the data layer (hystdisc.data), one file per module."""
