"""Results: the typed, versioned record of a discovery (``results.json``)."""
