"""Tests of the choice among fits (hystdisc.selection): families, current laws, the flowchart."""
