"""Typed loading of YAML documents into frozen dataclasses, with errors that name the place.

Scenes, configurations and experiment specs are all plain dataclasses. This module turns a
parsed YAML mapping into such a dataclass, checking unknown keys, missing fields and types,
and raises an `InputError` (or a subclass chosen by the caller) whose message names the file,
the dotted field path (``boxes[3].size``) and the reason. It never lets a ``KeyError`` or
``TypeError`` escape for bad input.

Supported field types: ``bool``, ``int``, ``float`` (finite; ints accepted), ``str``,
``Literal[...]``, ``X | None``, fixed-length ``tuple[T, T, T]``, variable ``tuple[T, ...]``,
``dict[str, scalar]``, and nested dataclasses. A field's declared range (`accepts.bounded`)
and its dataclass's ``relations`` are checked as each dataclass is built.
"""

from __future__ import annotations

import dataclasses
import math
import re
import types
import typing
from pathlib import Path
from typing import Any, Literal, TypeVar, get_args, get_origin, get_type_hints

import yaml

from drake_clutter.common.accepts import violations

T = TypeVar("T")

_YAML12_FLOAT = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")  # 1e-6, 5E5, 2.

EXIT_USAGE = 2  # exit status of every command and app on bad input


class InputError(ValueError):
    """Bad user input: names the file, the field (dotted path) and the reason."""

    def __init__(self, file: str | Path, field: str, reason: str):
        self.file = str(file)
        self.field = field
        self.reason = reason
        super().__init__(f"{self.file}: {field or '<document>'}: {reason}")


def _describe(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _join(prefix: str, name: str) -> str:
    return f"{prefix}.{name}" if prefix else name


class _Converter:
    """Converts parsed YAML into typed values; holds the file name and the error class."""

    def __init__(self, file: str | Path, error_cls: type[InputError]):
        self.file = file
        self.error_cls = error_cls

    def fail(self, field: str, reason: str) -> typing.NoReturn:
        raise self.error_cls(self.file, field, reason)

    def convert(self, tp: Any, value: Any, field: str) -> Any:
        origin = get_origin(tp)
        if dataclasses.is_dataclass(tp):
            return self.dataclass(tp, value, field)
        if origin is Literal:
            if value not in get_args(tp) or isinstance(value, bool):
                choices = ", ".join(repr(a) for a in get_args(tp))
                self.fail(field, f"must be one of {choices}, got {_describe(value)}")
            return value
        if origin in (typing.Union, types.UnionType):
            args = get_args(tp)
            if value is None and type(None) in args:
                return None
            inner = [a for a in args if a is not type(None)]
            if len(inner) == 1:
                return self.convert(inner[0], value, field)
            for candidate in inner:
                try:
                    return self.convert(candidate, value, field)
                except InputError:
                    continue
            self.fail(field, f"has the wrong type: {_describe(value)}")
        if origin is tuple:
            return self.tuple(tp, value, field)
        if origin is dict:
            return self.mapping(tp, value, field)
        return self.scalar(tp, value, field)

    def scalar(self, tp: Any, value: Any, field: str) -> Any:
        if tp is bool:
            if not isinstance(value, bool):
                self.fail(field, f"must be true or false, got {_describe(value)}")
            return value
        if tp is int:
            if isinstance(value, bool) or not isinstance(value, int):
                self.fail(field, f"must be an integer, got {_describe(value)}")
            return value
        if tp is float:
            if isinstance(value, str) and _YAML12_FLOAT.fullmatch(value.strip()):
                value = float(value)  # PyYAML (YAML 1.1) reads 1e-6 as a string
            if isinstance(value, bool) or not isinstance(value, int | float):
                self.fail(field, f"must be a number, got {_describe(value)}")
            if not math.isfinite(value):
                self.fail(field, f"must be a finite number, got {_describe(value)}")
            return float(value)
        if tp is str:
            if not isinstance(value, str):
                self.fail(field, f"must be a string, got {_describe(value)}")
            return value
        if tp is Any:
            return value
        raise TypeError(f"typed_yaml does not support the field type {tp!r}")  # programming error

    def tuple(self, tp: Any, value: Any, field: str) -> tuple:
        args = get_args(tp)
        if not isinstance(value, list | tuple):
            self.fail(field, f"must be a list, got {_describe(value)}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(self.convert(args[0], v, f"{field}[{i}]") for i, v in enumerate(value))
        if len(value) != len(args):
            self.fail(field, f"must have {len(args)} entries, got {len(value)}")
        return tuple(self.convert(a, v, f"{field}[{i}]")
                     for i, (a, v) in enumerate(zip(args, value, strict=True)))

    def mapping(self, tp: Any, value: Any, field: str) -> dict:
        key_tp, value_tp = get_args(tp)
        if not isinstance(value, dict):
            self.fail(field, f"must be a mapping, got {_describe(value)}")
        out = {}
        for key, item in value.items():
            if not isinstance(key, str):
                self.fail(field, f"keys must be strings, got {_describe(key)}")
            out[key] = self.convert(value_tp, item, _join(field, key))
        return out

    def dataclass(self, cls: Any, value: Any, field: str) -> Any:
        if not isinstance(value, dict):
            self.fail(field, f"must be a mapping, got {_describe(value)}")
        hints = get_type_hints(cls)
        fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
        for key in value:
            if key not in fields:
                known = ", ".join(fields)
                self.fail(_join(field, str(key)), f"unknown key (known keys: {known})")
        kwargs = {}
        for name, f in fields.items():
            if name in value:
                kwargs[name] = self.convert(hints[name], value[name], _join(field, name))
            elif f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
                self.fail(_join(field, name), "missing required field")
        obj = cls(**kwargs)
        for name, reason in violations(obj)[:1]:
            self.fail(_join(field, name), reason)
        return obj


def from_data(cls: type[T], data: Any, *, file: str | Path, error_cls=InputError,
              field: str = "") -> T:
    """Builds dataclass ``cls`` from parsed YAML ``data``; raises ``error_cls`` on bad input."""
    return _Converter(file, error_cls).convert(cls, data, field)


def parse_yaml_text(text: str, *, file: str | Path, error_cls=InputError) -> Any:
    """Parses YAML text (safe loader); syntax errors become ``error_cls`` with the line."""
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}" if mark else "document"
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise error_cls(file, where, f"unreadable YAML: {problem}") from None


def read_yaml_file(path: str | Path, *, error_cls=InputError) -> Any:
    """Reads and parses a YAML file; a missing or unreadable file becomes ``error_cls``."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise error_cls(path, "", "no such file") from None
    except IsADirectoryError:
        raise error_cls(path, "", "is a directory, not a YAML file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise error_cls(path, "", f"cannot be read: {exc}") from None
    return parse_yaml_text(text, file=path, error_cls=error_cls)


def to_data(obj: Any) -> Any:
    """Dataclass -> plain dicts/lists (field order kept; tuples become lists)."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: to_data(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, tuple | list):
        return [to_data(v) for v in obj]
    if isinstance(obj, dict):
        return {k: to_data(v) for k, v in obj.items()}
    return obj


class _FlowListDumper(yaml.SafeDumper):
    """Writes lists of scalars inline (``[0.1, 0.2, 0.3]``) and everything else as blocks."""


def _represent_list(dumper: yaml.SafeDumper, data: list) -> yaml.Node:
    flow = all(isinstance(v, int | float | str | bool) or v is None for v in data)
    return dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=flow)


_FlowListDumper.add_representer(list, _represent_list)


def dump_yaml(data: Any) -> str:
    """Deterministic YAML text for plain data (keys in insertion order)."""
    return yaml.dump(data, Dumper=_FlowListDumper, sort_keys=False, allow_unicode=True,
                     default_flow_style=False, width=100)


def apply_override(data: dict, dotted: str, value_text: str, *, file: str = "<command line>",
                   error_cls=InputError) -> dict:
    """Returns a copy of nested ``data`` with ``a.b.c`` set to the YAML-parsed ``value_text``."""
    keys = dotted.split(".")
    if not all(keys):
        raise error_cls(file, dotted, "expected a dotted key such as 'baseline.num_angles'")
    value = parse_yaml_text(value_text, file=file, error_cls=error_cls)
    out = dict(data)
    node = out
    for i, key in enumerate(keys[:-1]):
        child = node.get(key)
        if not isinstance(child, dict):
            raise error_cls(file, ".".join(keys[: i + 1]), "is not a section of the configuration")
        node[key] = dict(child)
        node = node[key]
    if keys[-1] not in node:
        raise error_cls(file, dotted, "unknown key")
    node[keys[-1]] = value
    return out
