"""Tests of the closing loop (hystdisc.closing): effects, structural effects, reselection, reduction, restarts."""
