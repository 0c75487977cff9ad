"""JSON encoding and validation derived once from a record's type annotations.

A message is a dataclass whose field annotations say all its JSON needs: the type, and in
``typing.Annotated`` markers the checks (:class:`Range`, :class:`Count`, :class:`Text`,
:class:`OneOf`, the bound :class:`Most` or :class:`Size` of a list or table), the JSON key where it
differs from the field's name (:class:`Key`) and whether a None is left out (:data:`OMIT_NONE`).
:func:`read` and :func:`write` compile a class's annotations once into a tree of small nodes that
read JSON into instances and write instances as JSON with the same checks, so whatever a process
sends its peers accept. Understood are dataclasses, TypedDicts, lists, tuples (``tuple[X, ...]``
and fixed-length), dicts, ``X | None``, unions of scalars (``str | int``) and free-form JSON
(:data:`FreeJSON`). A field missing on receipt takes its default; without one it is an error.

Every problem is a :class:`MessageError` ``"<where>: <problem>"``, ``where`` being the value's path
in the message (``percept.world/2.peers.b.x``); nothing else is raised, whatever the JSON.
"""

from __future__ import annotations

import dataclasses
import re
import types
import typing
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Annotated, NotRequired, Protocol, TypeAlias, TypeVar, Union, cast

#: Any JSON value, as ``json.loads`` gives it.
JSON: TypeAlias = bool | int | float | str | list["JSON"] | dict[str, "JSON"] | None

LIMIT = 1e12  # any number beyond this is garbage whatever it means

T = TypeVar("T")


class MessageError(ValueError):
    """A payload that is not a valid percept message: the one error a decoder raises."""


def fail(where: str, problem: str) -> MessageError:
    return MessageError(f"{where}: {problem}")


def show(value: object) -> str:
    """``value`` as an error message quotes it: its repr, cut at 40 characters."""
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


class _Invalid(Exception):
    """A problem with a value, and its path below the record read or written (outermost last):
    the path is put together only on the way out of an invalid message."""

    def __init__(self, problem: str) -> None:
        self.problem = problem
        self.trail: list[str] = []

    def at(self, step: str) -> _Invalid:
        self.trail.append(step)
        return self


class _Node(Protocol):
    def read(self, value: object) -> object: ...

    def write(self, value: object) -> JSON: ...


# -- markers of values (each is the node that checks such a value) ---------------------------------


@dataclass(frozen=True)
class Range:
    """A number in ``[lo, hi]``; JSON integers are read as floats."""

    lo: float = -LIMIT
    hi: float = LIMIT

    def read(self, value: object) -> float:
        # Compare before float(): a huge JSON integer would overflow the conversion.
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise _Invalid(f"expected a number, got {show(value)}")
        if not self.lo <= value <= self.hi:
            raise _Invalid(f"expected a number in [{self.lo:g}, {self.hi:g}], got {show(value)}")
        return float(value)

    write = read


@dataclass(frozen=True)
class Count:
    """An integer in ``[lo, hi]``."""

    lo: int = 0
    hi: int = 2**53

    def read(self, value: object) -> int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise _Invalid(f"expected an integer, got {show(value)}")
        if not self.lo <= value <= self.hi:
            raise _Invalid(f"expected an integer in [{self.lo}, {self.hi}], got {show(value)}")
        return value

    write = read


@dataclass(frozen=True)
class Text:
    """A string of at most ``most`` characters, matching ``pattern`` if given."""

    pattern: re.Pattern[str] | None = None
    most: int = 256

    def read(self, value: object) -> str:
        if not isinstance(value, str) or len(value) > self.most:
            raise _Invalid(
                f"expected a string of at most {self.most} characters, got {show(value)}"
            )
        # fullmatch: "$" lets a trailing newline through
        if self.pattern is not None and not self.pattern.fullmatch(value):
            raise _Invalid(f"{value!r} does not match {self.pattern.pattern}")
        return value

    write = read


@dataclass(frozen=True)
class OneOf:
    """One of a few strings."""

    values: tuple[str, ...]

    def read(self, value: object) -> str:
        if not isinstance(value, str) or value not in self.values:
            raise _Invalid(f"expected one of {', '.join(self.values)}, got {show(value)}")
        return value

    write = read


class _Flag:
    def read(self, value: object) -> bool:
        if not isinstance(value, bool):
            raise _Invalid(f"expected true or false, got {show(value)}")
        return value

    write = read


class _Free:
    """Any JSON value: it came from ``json.loads``, or ``json.dumps`` will check it."""

    def read(self, value: object) -> JSON:
        return cast(JSON, value)

    write = read


_FREE = _Free()
#: A free-form JSON field (its size is bounded by the payload's).
FreeJSON: TypeAlias = Annotated[JSON, _FREE]

# -- markers of lists, tables and fields -----------------------------------------------------------


@dataclass(frozen=True)
class Most:
    """At most ``n`` items of a list or entries of a table (``noun`` names them in errors)."""

    n: int
    noun: str = "items"


@dataclass(frozen=True)
class Size:
    """Exactly ``n`` items of a list."""

    n: int


@dataclass(frozen=True)
class Key:
    """The field's key in JSON, where it differs from the field's name (``from``)."""

    name: str


@dataclass(frozen=True)
class _OmitNone:
    pass


#: The field is left out of the JSON when it is None (it reads as None when missing).
OMIT_NONE = _OmitNone()


class Fields:
    """The annotated types of some fields of a record declared elsewhere (``perception``'s
    ``BoxPose``), by field name: ``Annotated[BoxPose, Fields(x=Annotated[float, Range(0, 1)])]``."""

    def __init__(self, **types: object) -> None:
        self.types = types


_AS_DECLARED = Fields()

# -- containers ------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _Optional:
    inner: _Node

    def read(self, value: object) -> object:
        return None if value is None else self.inner.read(value)

    def write(self, value: object) -> JSON:
        return None if value is None else self.inner.write(value)


@dataclass(frozen=True)
class _Either:
    """A union of scalars, chosen by the value's type; the last one reports a mismatch."""

    choices: tuple[tuple[type, _Node], ...]

    def _choose(self, value: object) -> _Node:
        for kind, node in self.choices:
            if isinstance(value, kind) and not (isinstance(value, bool) and kind is not bool):
                return node
        return self.choices[-1][1]

    def read(self, value: object) -> object:
        return self._choose(value).read(value)

    def write(self, value: object) -> JSON:
        return self._choose(value).write(value)


@dataclass(frozen=True)
class _Items:
    """A JSON list, read as a tuple or a list."""

    item: _Node
    most: int
    size: int | None
    noun: str
    as_tuple: bool

    def _check(self, value: object, kinds: type | tuple[type, ...]) -> list[object]:
        if not isinstance(value, kinds):
            raise _Invalid(f"expected a list, got {show(value)}")
        items = list(cast(Iterable[object], value))
        if len(items) > self.most:
            raise _Invalid(f"expected at most {self.most} items, got {len(items)}")
        if self.size is not None and len(items) != self.size:
            raise _Invalid(f"expected {self.size} {self.noun}, got {len(items)}")
        return items

    def read(self, value: object) -> object:
        out = _each(self._check(value, list), self.item.read)
        return tuple(out) if self.as_tuple else out

    def write(self, value: object) -> JSON:
        return cast(JSON, _each(self._check(value, (list, tuple)), self.item.write))


def _each(items: list[object], convert: Callable[[object], object]) -> list[object]:
    out = []
    for i, v in enumerate(items):
        try:
            out.append(convert(v))
        except _Invalid as err:
            raise err.at(f"[{i}]") from None
    return out


@dataclass(frozen=True)
class _Table:
    """A JSON object of any keys: a dict."""

    key: _Node
    value: _Node
    most: int
    noun: str

    def _check(self, value: object) -> dict[object, object]:
        if not isinstance(value, dict):
            raise _Invalid(f"expected an object, got {show(value)}")
        if len(value) > self.most:
            raise _Invalid(f"expected at most {self.most} {self.noun}, got {len(value)}")
        return value

    def read(self, value: object) -> object:
        return self._each(value, self.key.read, self.value.read)

    def write(self, value: object) -> JSON:
        return cast(JSON, self._each(value, self.key.write, self.value.write))

    def _each(
        self, value: object, key: Callable[[object], object], item: Callable[[object], object]
    ) -> dict[object, object]:
        out = {}
        for k, v in self._check(value).items():
            try:
                name = key(k)
            except _Invalid as err:
                raise err.at(" key") from None
            try:
                out[name] = item(v)
            except _Invalid as err:
                raise err.at(f".{k}") from None
        return out


@dataclass(frozen=True)
class _Field:
    name: str
    key: str
    node: _Node
    required: bool
    omit_none: bool


@dataclass(frozen=True)
class _Record:
    """A JSON object of known keys: a dataclass, or a TypedDict (read as a dict)."""

    cls: type
    fields: tuple[_Field, ...]  # in the order they are read and checked
    order: tuple[_Field, ...]  # in the order they are written
    typed_dict: bool

    def read(self, value: object) -> object:
        if not isinstance(value, dict):
            raise _Invalid(f"expected an object, got {show(value)}")
        out: dict[str, object] = {}
        for f in self.fields:
            if f.key in value:
                try:
                    out[f.name] = f.node.read(value[f.key])
                except _Invalid as err:
                    raise err.at(f".{f.key}") from None
            elif f.required:
                raise _Invalid(f"missing {f.key!r}")
        return out if self.typed_dict else self.cls(**out)

    def write(self, value: object) -> JSON:
        if not isinstance(value, dict if self.typed_dict else self.cls):
            raise _Invalid(f"expected a {self.cls.__name__}, got {show(value)}")
        out: dict[str, JSON] = {}
        for f in self.order:
            v = value.get(f.name, _ABSENT) if isinstance(value, dict) else getattr(value, f.name)
            if v is _ABSENT and f.required:
                raise _Invalid(f"missing {f.key!r}")
            if v is _ABSENT or (v is None and f.omit_none):
                continue
            try:
                out[f.key] = f.node.write(v)
            except _Invalid as err:
                raise err.at(f".{f.key}") from None
        return out


_ABSENT = object()  # a TypedDict's key left out


# -- compiling annotations -------------------------------------------------------------------------

_SCALARS: dict[object, _Node] = {float: Range(), int: Count(), str: Text(), bool: _Flag()}


def _node(hint: object, marks: tuple[object, ...] = ()) -> _Node:
    """The node for type ``hint`` with the markers ``marks`` that annotate it."""
    if typing.get_origin(hint) is Annotated:
        base, *more = typing.get_args(hint)
        return _node(base, (*marks, *more))
    if _FREE in marks:
        return _FREE
    leaf = [m for m in marks if isinstance(m, Range | Count | Text | OneOf)]
    if leaf:
        return cast(_Node, leaf[-1])
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin in (Union, types.UnionType):
        choices = [a for a in args if a is not type(None)]
        if len(choices) < len(args):
            inner = choices[0] if len(choices) == 1 else Union[tuple(choices)]  # noqa: UP007
            return _Optional(_node(inner, marks))
        return _Either(tuple((_kind(a), _node(a)) for a in choices))
    if origin in (list, tuple):
        return _items(hint, origin, args, marks)
    if origin is dict:
        most = _most(marks, hint)
        return _Table(_node(args[0]), _node(args[1]), most.n, most.noun)
    if hint in _SCALARS:
        return _SCALARS[hint]
    if isinstance(hint, type) and (dataclasses.is_dataclass(hint) or typing.is_typeddict(hint)):
        given = [m for m in marks if isinstance(m, Fields)]
        return _record(hint, given[0] if given else _AS_DECLARED)
    raise TypeError(f"no JSON codec for {hint!r}")


def _kind(hint: object) -> type:
    base = _base(hint)
    if base not in _SCALARS:
        raise TypeError(f"a union of {hint!r} is not a union of scalars")
    return cast(type, base)


def _items(
    hint: object, origin: object, args: tuple[object, ...], marks: tuple[object, ...]
) -> _Node:
    if origin is tuple and args and args[-1] is not Ellipsis:  # fixed length: tuple[X, X, X]
        if any(a != args[0] for a in args):
            raise TypeError(f"{hint!r}: a fixed-length tuple's items must be of one type")
        size: int | None = len(args)
    else:
        size = next((m.n for m in marks if isinstance(m, Size)), None)
    if size is None:
        most = _most(marks, hint)
        bound, noun = most.n, most.noun
    else:
        bound, noun = size, "numbers" if _base(args[0]) is float else "items"
    return _Items(_node(args[0]), bound, size, noun, as_tuple=origin is tuple)


def _base(hint: object) -> object:
    return typing.get_args(hint)[0] if typing.get_origin(hint) is Annotated else hint


def _most(marks: tuple[object, ...], hint: object) -> Most:
    found = [m for m in marks if isinstance(m, Most)]
    if not found:
        raise TypeError(f"{hint!r} needs a bound: Most(n)")
    return found[-1]


_RECORDS: dict[tuple[type, Fields], _Record] = {}


def _record(cls: type, fields: Fields) -> _Record:
    """The compiled record ``cls``, compiled on first use (twice at worst, by two threads)."""
    found = _RECORDS.get((cls, fields))
    if found is None:
        found = _RECORDS[cls, fields] = _compile(cls, fields)
    return found


def _compile(cls: type, given: Fields) -> _Record:
    hints = typing.get_type_hints(cls, include_extras=True)
    if typing.is_typeddict(cls):
        names = list(hints)
        defaults = {n: typing.get_origin(hints[n]) is NotRequired for n in names}
    else:
        names = [f.name for f in dataclasses.fields(cls)]
        defaults = {
            f.name: f.default is not dataclasses.MISSING
            or f.default_factory is not dataclasses.MISSING
            for f in dataclasses.fields(cls)
        }
    fields = []
    for name in names:
        hint = given.types.get(name, hints[name])
        marks: tuple[object, ...] = ()
        if typing.get_origin(hint) is Annotated:
            hint, *rest = typing.get_args(hint)
            marks = tuple(rest)
        if typing.get_origin(hint) is NotRequired:
            hint = typing.get_args(hint)[0]
        key = next((m.name for m in marks if isinstance(m, Key)), name)
        node = _node(hint, tuple(m for m in marks if not isinstance(m, Key | _OmitNone)))
        fields.append(_Field(name, key, node, not defaults[name], OMIT_NONE in marks))
    keys: tuple[str, ...] | None = getattr(cls, "KEYS", None)
    order = fields
    if keys is not None:
        by_key = {f.key: f for f in fields}
        if sorted(keys) != sorted(by_key):
            raise TypeError(f"{cls.__name__}.KEYS {keys} are not the keys {tuple(by_key)}")
        order = [by_key[k] for k in keys]
    return _Record(cls, tuple(fields), tuple(order), typing.is_typeddict(cls))


def read(cls: type[T], value: object, where: str) -> T:
    """An instance of record ``cls`` from the JSON ``value``; ``where`` names it in errors."""
    try:
        return cast(T, _record(cls, _AS_DECLARED).read(value))
    except _Invalid as err:
        raise _error(where, err) from None


def write(record: object, where: str) -> dict[str, JSON]:
    """Record ``record`` as a JSON object, checked as :func:`read` checks it."""
    try:
        return cast(dict[str, JSON], _record(type(record), _AS_DECLARED).write(record))
    except _Invalid as err:
        raise _error(where, err) from None


def _error(where: str, err: _Invalid) -> MessageError:
    return fail(where + "".join(reversed(err.trail)), err.problem)
