"""Typed, validated configuration from TOML.

The lower folders describe the parameters they need as plain dataclasses; this module turns a
TOML table into such a dataclass and says exactly what is wrong when it cannot. Every error names
the file, the key path and what was expected::

    config/robots/op3.toml: joints[1].id: expected an integer 0-252, got "x"

Conventions a dataclass field can use, all through ``dataclasses.field(metadata=...)`` so that the
lower folders need not import this module:

- ``metadata={"min": 0, "max": 252}``: inclusive bounds for numbers,
- ``metadata={"doc": "..."}``: what the key means (shown by ``percept config --explain``).

Cross-field rules live in the dataclass's ``__post_init__`` and raise :class:`ValueError`; the
message is reported against the table's key path (:class:`FieldError` names a key inside it).
Unknown keys are errors: a typo must not pass silently. Relative paths (fields typed
:class:`pathlib.Path`) are resolved against the directory of the file they were written in.
"""

from __future__ import annotations

import dataclasses
import enum
import json
import math
import tomllib
import types
import typing
from collections.abc import Mapping
from datetime import date, datetime, time
from pathlib import Path
from typing import (
    Any,
    ClassVar,
    Literal,
    Protocol,
    TypeAlias,
    TypeGuard,
    TypeVar,
    Union,
    get_args,
    get_origin,
)

#: A value of parsed TOML, as :mod:`tomllib` gives it.
TomlValue: TypeAlias = (
    str | int | float | bool | datetime | date | time | list["TomlValue"] | dict[str, "TomlValue"]
)
#: A type annotation read at run time: a class, ``X | None``, ``list[X]``, ``Literal[...]``...
#: Python has no type for such forms yet (PEP 747), so they are objects inspected here.
TypeForm: TypeAlias = object
#: A dataclass field's metadata: ``min``, ``max`` and ``doc`` (see the module text).
Meta: TypeAlias = Mapping[str, object]


class _Dataclass(Protocol):
    """A class made by ``@dataclass``: what :func:`dataclasses.fields` reads."""

    # A field of any type: the Protocol stands for every dataclass.
    __dataclass_fields__: ClassVar[dict[str, dataclasses.Field[Any]]]


T = TypeVar("T", bound=_Dataclass)

_MISSING = object()


class ConfigError(Exception):
    """A configuration problem: the file, the key path and what was expected."""

    def __init__(self, file: str | Path, key: str, problem: str) -> None:
        self.file = str(file)
        self.key = key
        self.problem = problem
        where = f"{self.file}: {key}" if key else self.file
        super().__init__(f"{where}: {problem}")


class FieldError(ValueError):
    """A cross-field rule broken at one key inside the table (``joints[2].model``): raised by
    a ``__post_init__`` so the error names that key, not just the table."""

    def __init__(self, key: str, problem: str) -> None:
        self.key = key
        self.problem = problem
        super().__init__(f"{key}: {problem}")


def _show(value: object) -> str:
    """A value as it would look in the TOML file."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str | int | float):
        try:
            return json.dumps(value)
        except ValueError:  # an integer of more than 4300 digits, Python's limit for str()
            return "an integer too long to show"
    if isinstance(value, Mapping):
        return "a table"
    if isinstance(value, list):
        return "a list"
    return repr(value)


def _join(path: str, key: str | int) -> str:
    if isinstance(key, int):
        return f"{path}[{key}]"
    return f"{path}.{key}" if path else key


def _bounds(meta: Meta) -> str:
    lo, hi = meta.get("min"), meta.get("max")
    if lo is not None and hi is not None:
        return f" {lo}-{hi}"
    if lo is not None:
        return f" >= {lo}"
    if hi is not None:
        return f" <= {hi}"
    return ""


def describe(tp: TypeForm, meta: Meta | None = None) -> str:
    """What a value of type ``tp`` looks like, in words, for error messages."""
    meta = meta or {}
    origin, args = get_origin(tp), get_args(tp)
    if tp is bool:
        return "true or false"
    if tp is int:
        return "an integer" + _bounds(meta)
    if tp is float:
        return "a number" + _bounds(meta)
    if tp is str:
        return "a string"
    if tp is Path:
        return "a path (string)"
    if isinstance(tp, type) and issubclass(tp, enum.Enum):
        return "one of " + ", ".join(_show(m.value) for m in tp)
    if origin is Literal:
        return "one of " + ", ".join(_show(a) for a in args)
    if origin in (Union, types.UnionType):
        inner = [a for a in args if a is not type(None)]
        return " or ".join(describe(a, meta) for a in inner)
    if origin is list or (origin is tuple and args[-1:] == (Ellipsis,)):
        return f"a list of {_plural(describe(args[0], meta))}"
    if origin is tuple:
        return f"a list of {len(args)} {_plural(describe(args[0], meta))}"
    if origin is dict:
        return f"a table of {_plural(describe(args[1], meta))}"
    if dataclasses.is_dataclass(tp):
        return "a table"
    return getattr(tp, "__name__", str(tp))


def _plural(words: str) -> str:
    for article in ("an ", "a "):
        if words.startswith(article):
            head, _, rest = words[len(article) :].partition(" ")
            return f"{head}s{' ' + rest if rest else ''}"
    return words


class _Builder:
    """Converts one file's TOML data into dataclasses, remembering where it came from."""

    def __init__(self, file: str | Path, base_dir: Path) -> None:
        self.file = file
        self.base_dir = base_dir

    def fail(self, key: str, problem: str) -> typing.NoReturn:
        raise ConfigError(self.file, key, problem)

    def expected(self, key: str, tp: TypeForm, meta: Meta, got: object) -> typing.NoReturn:
        self.fail(key, f"expected {describe(tp, meta)}, got {_show(got)}")

    def value(self, tp: TypeForm, raw: TomlValue, key: str, meta: Meta) -> object:
        """``raw`` as a value of ``tp`` (an instance of whatever it names)."""
        origin, args = get_origin(tp), get_args(tp)
        # A type hint naming a dataclass is the class itself, never an instance.
        if _is_table(tp):
            if not isinstance(raw, Mapping):
                self.expected(key, tp, meta, raw)
            return self.table(tp, raw, key)
        if origin in (Union, types.UnionType):
            inner = [a for a in args if a is not type(None)]
            for option in inner:
                try:
                    return self.value(option, raw, key, meta)
                except ConfigError:
                    continue
            self.expected(key, tp, meta, raw)
        if origin is Literal:
            for allowed in args:
                if raw == allowed and type(raw) in (type(allowed), int, float):
                    return allowed
            self.expected(key, tp, meta, raw)
        if origin is list or (origin is tuple and args[-1:] == (Ellipsis,)):
            if not isinstance(raw, list):
                self.expected(key, tp, meta, raw)
            items = [self.value(args[0], v, _join(key, i), meta) for i, v in enumerate(raw)]
            return items if origin is list else tuple(items)
        if origin is tuple:
            if not isinstance(raw, list) or len(raw) != len(args):
                self.expected(key, tp, meta, raw)
            return tuple(
                self.value(a, v, _join(key, i), meta)
                for i, (a, v) in enumerate(zip(args, raw, strict=True))
            )
        if origin is dict:
            if not isinstance(raw, Mapping):
                self.expected(key, tp, meta, raw)
            return {
                str(k): self.value(args[1], v, _join(key, str(k)), meta) for k, v in raw.items()
            }
        return self.scalar(tp, raw, key, meta)

    def scalar(self, tp: TypeForm, raw: TomlValue, key: str, meta: Meta) -> object:
        if tp is bool:
            if not isinstance(raw, bool):
                self.expected(key, tp, meta, raw)
            return raw
        if tp is int or tp is float:
            # An integer, or (for a float) a finite float; never a bool.
            if isinstance(raw, bool) or not isinstance(raw, int | float):
                self.expected(key, tp, meta, raw)
            if isinstance(raw, float) and (tp is int or not math.isfinite(raw)):
                self.expected(key, tp, meta, raw)
            lo, hi = _limit(meta, "min"), _limit(meta, "max")
            if (lo is not None and raw < lo) or (hi is not None and raw > hi):
                self.expected(key, tp, meta, raw)
            try:
                return int(raw) if tp is int else float(raw)
            except OverflowError:  # an integer beyond the largest float
                self.expected(key, tp, meta, raw)
        if tp is str:
            if not isinstance(raw, str):
                self.expected(key, tp, meta, raw)
            return raw
        if tp is Path:
            if not isinstance(raw, str) or not raw:
                self.expected(key, tp, meta, raw)
            try:
                path = Path(raw).expanduser()
            except RuntimeError:  # "~user/..." for a user without a home directory
                self.fail(key, f"cannot expand {_show(raw)}: no such user's home directory")
            return path if path.is_absolute() else (self.base_dir / path)
        if isinstance(tp, type) and issubclass(tp, enum.Enum):
            for member in tp:
                if raw == member.value:
                    return member
            self.expected(key, tp, meta, raw)
        if tp is Any:
            return raw
        raise TypeError(f"config type {tp!r} at {key} is not supported")

    def table(self, cls: type[T], raw: Mapping[str, TomlValue], key: str) -> T:
        hints = typing.get_type_hints(cls)
        fields = {f.name: f for f in dataclasses.fields(cls) if f.init}
        for name in raw:
            if name not in fields:
                known = ", ".join(fields)
                self.fail(_join(key, name), f"unknown key; expected one of: {known}")
        kwargs: dict[str, object] = {}
        for name, f in fields.items():
            path = _join(key, name)
            if name in raw:
                kwargs[name] = self.value(hints[name], raw[name], path, f.metadata)
            elif f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
                self.fail(path, f"missing; expected {describe(hints[name], f.metadata)}")
        try:
            return cls(**kwargs)
        except FieldError as err:
            self.fail(_join(key, err.key), err.problem)
        except (ValueError, TypeError) as err:
            self.fail(key or "(top level)", str(err))


def read_toml(path: str | Path) -> dict[str, TomlValue]:
    """The TOML file's data, or a :class:`ConfigError` saying why it cannot be read."""
    path = Path(path)
    try:
        with path.open("rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise ConfigError(path, "", "file not found") from None
    except OSError as err:
        raise ConfigError(path, "", f"cannot read: {err.strerror}") from None
    except ValueError as err:  # TOMLDecodeError, bad UTF-8, an integer too long to parse
        raise ConfigError(path, "", f"invalid TOML: {err}") from None
    except RecursionError:  # arrays or inline tables nested some thousand levels deep
        raise ConfigError(path, "", "invalid TOML: nested too deeply") from None


def build(cls: type[T], data: Mapping[str, TomlValue], file: str | Path, key: str = "") -> T:
    """Build dataclass ``cls`` from ``data`` read from ``file``; ``key`` is where the table sits."""
    return _Builder(file, Path(file).parent).table(cls, data, key)


def load(cls: type[T], path: str | Path) -> T:
    """Read a TOML file into dataclass ``cls``."""
    return build(cls, read_toml(path), path)


def fields_doc(cls: type, prefix: str = "") -> list[tuple[str, str, str, str]]:
    """(key, type in words, default, doc) for every key of ``cls``, nested tables flattened;
    the keys of each table in a list of tables (``[[joints]]``) follow as ``joints[].name``, and
    those of a table of tables as ``joints.NAME.offset``."""
    rows: list[tuple[str, str, str, str]] = []
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        tp, key = hints[f.name], _join(prefix, f.name)
        if _is_table(tp):
            rows.extend(fields_doc(tp, key))
            continue
        if f.default is not dataclasses.MISSING:
            default = _show_default(f.default)
        elif f.default_factory is not dataclasses.MISSING:
            default = _show_default(f.default_factory())
        else:
            default = "(required)"
        rows.append((key, describe(tp, f.metadata), default, f.metadata.get("doc", "")))
        origin, args = get_origin(tp), get_args(tp)
        if origin in (list, tuple) and args and _is_table(args[0]):
            rows.extend(fields_doc(args[0], f"{key}[]"))
        elif origin is dict and _is_table(args[1]):
            rows.extend(fields_doc(args[1], f"{key}.NAME"))
    return rows


def _is_table(tp: object) -> TypeGuard[type[_Dataclass]]:
    """Whether the annotation ``tp`` is a dataclass, read as a TOML table."""
    return isinstance(tp, type) and dataclasses.is_dataclass(tp)


def _limit(meta: Meta, name: str) -> float | None:
    """The ``min`` or ``max`` a field's metadata sets, if any."""
    value = meta.get(name)
    return value if isinstance(value, int | float) else None


def _show_default(value: object) -> str:
    """A default as it would be written in TOML (a tuple of numbers as an array)."""
    if value is None:
        return "(none)"
    if isinstance(value, tuple | list) and all(isinstance(v, str | int | float) for v in value):
        return "[" + ", ".join(_show(v) for v in value) + "]"
    if isinstance(value, tuple | list | Mapping):
        return "[]" if not value else _show(value)
    return _show(value)
