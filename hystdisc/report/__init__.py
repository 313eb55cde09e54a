"""The self-contained HTML model-comparison report and its Markdown summary."""
