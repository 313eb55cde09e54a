"""The ``results.json`` schema: its version and the migration of older tables."""

from __future__ import annotations

from hystdisc.results.record import SchemaError

#: The ``results.json`` schema this version writes (1: hystdisc 0.1, no ``schema_version``).
SCHEMA_VERSION = 5


def migrate(data: dict) -> dict:
    """A ``results.json`` table of any known schema as a table of :data:`SCHEMA_VERSION`.

    Schema 1 differs only by the missing ``schema_version``; schema 2 by the keys schema 3
    added (absent: their attributes keep their defaults, None or empty).

    Raises
    ------
    SchemaError
        For a schema newer than this version's or one that is no integer.

    Examples
    --------
    >>> migrate({"family": "dahl"})
    {'schema_version': 5, 'family': 'dahl'}
    """
    version = data.get("schema_version", 1)
    if isinstance(version, bool) or not isinstance(version, int) or version < 1:
        raise SchemaError("schema_version", f"not a schema number ({version!r})")
    if version > SCHEMA_VERSION:
        raise SchemaError(
            "schema_version",
            f"{version}, newer than this hystdisc reads ({SCHEMA_VERSION}); fix: update hystdisc",
        )
    rest = {k: v for k, v in data.items() if k != "schema_version"}
    return {"schema_version": SCHEMA_VERSION, **rest}
