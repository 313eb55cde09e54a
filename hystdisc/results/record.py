"""The base of every typed ``results.json`` record: JSON form, key order, rounding.

A record is a dataclass whose attribute names are its ``results.json`` keys. It remembers
the keys (and their order) of the table it was read from, so that a file of an older
schema, or an entry whose optional keys are absent (an accepted effect's parameters have
no ``identifiable``), is written back as it was read; keys this version does not know are
kept in :attr:`Record.extra`. Read access by key (``entry["rms"]``) mirrors the JSON and
keeps code written against the plain dicts of schema 1 working.

Examples
--------
>>> from dataclasses import dataclass, field
>>> @dataclass
... class Point(Record):
...     x: float = 0.0
...     y: float | None = None
...     extra: dict = field(default_factory=dict)
>>> p = Point.from_dict({"y": 2.0, "x": 1.0, "label": "a"})
>>> p.x, p["y"], p.extra, p.to_dict()
(1.0, 2.0, {'label': 'a'}, {'y': 2.0, 'x': 1.0, 'label': 'a'})
>>> Point(x=3.0).to_dict()  # built in code: every attribute is written
{'x': 3.0, 'y': None}
>>> Point.make(y=1 / 3, x=np.float64(2.0)).to_dict()  # made from values: rounded, as given
{'y': 0.3333333333, 'x': 2.0}
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterator
from typing import Any, ClassVar

import numpy as np

#: Floats in ``results.json`` are rounded to this many significant digits (stable bytes).
SIG_DIGITS = 10


class SchemaError(ValueError):
    """A ``results.json`` table whose structure does not fit the schema (``where``: its key)."""

    def __init__(self, where: str, what: str) -> None:
        super().__init__(f"{where} is {what}")
        self.where = where


def round_json(x: Any) -> Any:
    """Round floats to :data:`SIG_DIGITS` significant digits; NaN and inf become None.

    Examples
    --------
    >>> round_json({"a": [1.23456789012345, float("nan")], "b": (np.int64(2), np.bool_(True))})
    {'a': [1.23456789, None], 'b': [2, True]}
    """
    if isinstance(x, dict):
        return {k: round_json(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [round_json(v) for v in x]
    if isinstance(x, (np.floating, float)):
        x = float(x)
        if not math.isfinite(x):
            return None
        return float(f"{x:.{SIG_DIGITS}g}")
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def to_json_value(x: Any) -> Any:
    """The plain JSON form of a value that may hold records."""
    if isinstance(x, Record):
        return x.to_dict()
    if isinstance(x, dict):
        return {k: to_json_value(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [to_json_value(v) for v in x]
    return x


def table(where: str, value: Any) -> dict:
    """``value`` when it is a JSON object, else a :class:`SchemaError`."""
    if not isinstance(value, dict):
        raise SchemaError(where, f"not a table ({type(value).__name__})")
    return value


def rows(where: str, value: Any) -> list:
    """``value`` when it is a JSON array, else a :class:`SchemaError`."""
    if not isinstance(value, list):
        raise SchemaError(where, f"not a list ({type(value).__name__})")
    return value


def record_of(cls: type[Record]) -> Callable[[str, Any], Any]:
    """Converter: a table into ``cls`` (null stays None)."""

    def conv(where: str, value: Any) -> Any:
        return None if value is None else cls.from_dict(value, where)

    return conv


def table_of(cls: type[Record]) -> Callable[[str, Any], Any]:
    """Converter: a table of tables into ``{key: cls}``."""

    def conv(where: str, value: Any) -> Any:
        if value is None:
            return None
        return {k: cls.from_dict(v, f"{where}.{k}") for k, v in table(where, value).items()}

    return conv


def list_of(cls: type[Record]) -> Callable[[str, Any], Any]:
    """Converter: a list of tables into ``[cls, ...]``."""

    def conv(where: str, value: Any) -> Any:
        if value is None:
            return None
        return [cls.from_dict(v, f"{where}[{k}]") for k, v in enumerate(rows(where, value))]

    return conv


class Record:
    """Mixin of the ``results.json`` dataclasses (see the module docstring).

    Subclasses are dataclasses; :attr:`_nested` maps an attribute to the converter of its
    JSON value (records, tables or lists of records). Every subclass ends with the field
    ``extra``.
    """

    _nested: ClassVar[dict[str, Callable[[str, Any], Any]]] = {}
    #: Set by :meth:`from_dict` on the instance: the keys of the table read, in order
    #: (None: built in code, every attribute is written).
    _keys: ClassVar[tuple[str, ...] | None] = None

    @classmethod
    def from_dict(cls, data: Any, where: str | None = None):
        """Build the record from its (rounded) ``results.json`` table.

        Raises
        ------
        SchemaError
            When a table or list of the schema is something else.
        """
        where = where or cls.__name__
        data = table(where, data)
        names = [f.name for f in dataclasses.fields(cls) if f.name != "extra"]
        kw: dict[str, Any] = {}
        extra: dict[str, Any] = {}
        for key, value in data.items():
            if key in names:
                conv = cls._nested.get(key)
                kw[key] = conv(f"{where}.{key}", value) if conv else value
            else:
                extra[key] = value
        obj = cls(**kw, extra=extra)
        obj.remember_keys(tuple(data))
        return obj

    @classmethod
    def make(cls, **values: Any):
        """The record of ``values``, made in code as :meth:`from_dict` reads a table.

        Each value is rounded as ``results.json`` rounds it (:func:`round_json`: floats to
        :data:`SIG_DIGITS` significant digits, NaN and inf to None, tuples to lists), and
        the keys are written in the order given; a key that is no attribute is kept in
        ``extra``. Nested records are given as records (a :meth:`make` of their own).

        Returns
        -------
        Record
            The record (of the class it is called on).
        """
        names = {f.name for f in dataclasses.fields(cls)} - {"extra"}
        kw: dict[str, Any] = {}
        extra: dict[str, Any] = {}
        for key, value in values.items():
            (kw if key in names else extra)[key] = round_json(value)
        obj = cls(**kw, extra=extra)
        obj.remember_keys(tuple(values))
        return obj

    def remember_keys(self, keys: tuple[str, ...]) -> None:
        """Keep the order of the keys this record was read with (writing keeps it)."""
        self._keys = tuple(keys)  # type: ignore[misc]

    def _present(self) -> list[str]:
        """The keys to write: those read (in order), then attributes set since."""
        out = list(getattr(self, "_keys", None) or ())
        for f in dataclasses.fields(self):
            if f.name == "extra" or f.name in out:
                continue
            default = (
                f.default_factory() if f.default_factory is not dataclasses.MISSING else f.default
            )
            if getattr(self, "_keys", None) is None or getattr(self, f.name) != default:
                out.append(f.name)
        for k in self.extra:
            if k not in out:
                out.append(k)
        return out

    def to_dict(self) -> dict:
        """The record as its plain ``results.json`` table."""
        return {k: to_json_value(self[k]) for k in self._present()}

    # -- read access by key, as in schema 1 (plain dicts)
    def __getitem__(self, key: str) -> Any:
        if key in self.extra:
            return self.extra[key]
        if key != "extra" and key in {f.name for f in dataclasses.fields(self)}:
            if key in self._present():
                return getattr(self, key)
        raise KeyError(key)

    def get(self, key: str, default: Any = None) -> Any:
        """The value of ``key`` as in the JSON table, or ``default`` when it is absent."""
        try:
            return self[key]
        except KeyError:
            return default

    def __contains__(self, key: object) -> bool:
        return isinstance(key, str) and key in self._present()

    def keys(self) -> list[str]:
        """The JSON keys of this record, in order."""
        return self._present()

    def __iter__(self) -> Iterator[str]:
        return iter(self._present())

    def __len__(self) -> int:
        return len(self._present())
