"""Data in: the dataset, units, readers (CSV, tables, .mat), validation, noise and writers."""
