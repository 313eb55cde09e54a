"""Tests of the command line (hystdisc.cli), one file per command where it has its own."""
