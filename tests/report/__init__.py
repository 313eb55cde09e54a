"""Tests of the HTML report and its Markdown summary (hystdisc.report)."""
