"""Building the records from a resolved scene dict, by one rule (:mod:`parmpm.scene.records`):
tables become the record their field is annotated with, lists tuples, ``materials`` a
:class:`FrozenMap`; a key no field names is a ``TypeError``."""
from __future__ import annotations

import dataclasses
import functools
import types
import typing
from collections.abc import Mapping
from typing import Any

class FrozenMap(Mapping):
    """A read-only mapping (``materials``): unlike ``types.MappingProxyType`` it pickles and
    copies, as the records do."""

    __slots__ = ("_items",)

    def __init__(self, items: dict):
        self._items = dict(items)

    def __getitem__(self, key):
        return self._items[key]

    def __iter__(self):
        return iter(self._items)

    def __len__(self) -> int:
        return len(self._items)

    def __repr__(self) -> str:
        return repr(self._items)



@functools.cache
def _field_types(cls) -> dict[str, Any]:
    hints = typing.get_type_hints(cls)
    return {f.name: hints[f.name] for f in dataclasses.fields(cls)}


def build(cls, table: dict):
    """The record ``cls`` of a resolved table (module doc: the rule)."""
    types_ = _field_types(cls)
    extra = [k for k in table if k not in types_]
    if extra:
        raise TypeError(f"{cls.__name__} has no field for key(s) {', '.join(map(str, extra))} "
                        "of the resolved scene (parmpm.scene.records)")
    return cls(**{k: _convert(types_[k], v) for k, v in table.items()})


def _convert(hint, value):
    """``value`` as the field annotated ``hint`` holds it."""
    if value is None:
        return None
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (typing.Union, types.UnionType):
        many = next((a for a in args if typing.get_origin(a) is tuple and typing.get_args(a)
                     and dataclasses.is_dataclass(typing.get_args(a)[0])), None)
        if many is not None and isinstance(value, list):  # ``tuple[Part, ...] | None``
            return _convert(many, value)
        record = next((a for a in args if dataclasses.is_dataclass(a)), None)
        return build(record, value) if record and isinstance(value, dict) else _frozen(value)
    if dataclasses.is_dataclass(hint):
        return build(hint, value)
    if origin is tuple and args and dataclasses.is_dataclass(args[0]):
        return tuple(build(args[0], v) for v in value)
    if origin is Mapping:
        return FrozenMap({k: build(args[1], v) for k, v in value.items()})
    return _frozen(value)


def _frozen(value):
    """Lists as tuples, all the way down."""
    if isinstance(value, list):
        return tuple(_frozen(v) for v in value)
    if isinstance(value, dict):
        raise TypeError(f"a table where the records expect a value: {value!r}")
    return value
