"""A small JSON Schema (draft 2020-12) validator for frbench's own schemas.

frbench needs no third-party validator: this one covers the keywords its schemas
use (``type``, ``const``, ``enum``, ``anyOf``, ``$ref``, ``properties``,
``required``, ``additionalProperties``, ``propertyNames``, ``min/maxProperties``,
``items``, ``min/maxItems``, ``uniqueItems``, ``minimum``, ``maximum``,
``min/maxLength``, ``pattern``) and refuses a schema that uses any other
validation keyword, so a schema edit cannot silently go unchecked.

It stops at the first violation and reports it as ``path: problem`` with a
path such as ``cells[3].success_rate``. Non-finite numbers are refused
everywhere: Python's ``json`` reads ``NaN``/``Infinity`` unless told otherwise,
and frbench's readers turn them into :class:`NonFinite` markers that this
validator names.
"""

from __future__ import annotations

import re
from functools import lru_cache
from typing import Any, Mapping

from frbench.errors import ResultsError

#: Keywords that only annotate; everything else must be implemented below.
_ANNOTATIONS = {"$schema", "$id", "$defs", "$comment", "title", "description", "examples", "default"}
_IMPLEMENTED = {
    "type", "const", "enum", "anyOf", "$ref", "properties", "required", "additionalProperties",
    "propertyNames", "minProperties", "maxProperties", "items", "minItems", "maxItems", "uniqueItems",
    "minimum", "maximum", "minLength", "maxLength", "pattern",
}
_KEY = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_-]{0,63}$")


class NonFinite:
    """What strict JSON readers put where a file says ``NaN``, ``Infinity`` or ``-Infinity``."""

    __slots__ = ("text",)

    def __init__(self, text: str) -> None:
        self.text = text

    def __repr__(self) -> str:
        return self.text

    def __eq__(self, other: object) -> bool:
        return isinstance(other, NonFinite) and other.text == self.text

    def __hash__(self) -> int:
        return hash(("NonFinite", self.text))


class SchemaViolation(ResultsError):
    """A value that breaks a schema; ``path`` names the field (``''`` for the whole document)."""

    def __init__(self, path: str, problem: str, *, type_mismatch: bool = False) -> None:
        self.path = path
        self.problem = problem
        self.type_mismatch = type_mismatch
        super().__init__(f"{path or '(top level)'}: {problem}")


def join_path(path: str, key: str | int) -> str:
    """``cells`` + 3 -> ``cells[3]``; ``robots`` + ``go2`` -> ``robots.go2``; odd keys are quoted."""
    if isinstance(key, int):
        return f"{path}[{key}]"
    if _KEY.match(key):
        return f"{path}.{key}" if path else key
    return f"{path}[{_short(key)}]"


def _short(value: Any, limit: int = 60) -> str:
    """A one-line, bounded repr of a value for messages."""
    if isinstance(value, NonFinite):
        return value.text
    if isinstance(value, (dict, list)):
        return f"a JSON {'object' if isinstance(value, dict) else 'array'}"
    text = repr(value)
    if value is None:
        text = "null"
    elif isinstance(value, bool):
        text = "true" if value else "false"
    text = text.encode("ascii", "backslashreplace").decode()
    return text if len(text) <= limit else text[: limit - 4] + "...'"


def json_type(value: Any) -> str:
    """The JSON type name of a parsed value."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "boolean"
    if isinstance(value, int):
        return "integer"
    if isinstance(value, float):
        return "number"
    if isinstance(value, str):
        return "string"
    if isinstance(value, list):
        return "array"
    if isinstance(value, dict):
        return "object"
    if isinstance(value, NonFinite):
        return "non-finite number"
    return type(value).__name__


def _is_type(value: Any, name: str) -> bool:
    if name == "null":
        return value is None
    if name == "boolean":
        return isinstance(value, bool)
    if name == "integer":
        if isinstance(value, bool):
            return False
        return isinstance(value, int) or (isinstance(value, float) and value.is_integer())
    if name == "number":
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if name == "string":
        return isinstance(value, str)
    if name == "array":
        return isinstance(value, list)
    if name == "object":
        return isinstance(value, dict)
    raise ValueError(f"unknown JSON Schema type {name!r}")


def _same(a: Any, b: Any) -> bool:
    """JSON equality: 1 == 1.0, but true != 1 and "1" != 1."""
    if isinstance(a, bool) or isinstance(b, bool):
        return type(a) is type(b) and a == b
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, (int, float)) and isinstance(b, (int, float)):
        return a == b
    return type(a) is type(b) and a == b


@lru_cache(maxsize=None)
def _regex(pattern: str) -> re.Pattern:
    return re.compile(pattern)


def format_path(path: tuple | None) -> str:
    """A lazily built path ``(parent, key)`` -> ``cells[3].success_rate``."""
    keys = []
    while path is not None:
        path, key = path
        keys.append(key)
    text = ""
    for key in reversed(keys):
        text = join_path(text, key)
    return text


def _fail(path: tuple | None, problem: str, *, type_mismatch: bool = False) -> None:
    raise SchemaViolation(format_path(path), problem, type_mismatch=type_mismatch)


_INF = float("inf")


class Validator:
    """Validates instances against a schema; ``registry`` maps ``$id`` to schemas for cross-file ``$ref``.

    Schemas are compiled once into nested check functions; paths are only
    formatted when a check fails, so validating a results file of thousands of
    episodes takes a fraction of a second.
    """

    def __init__(self, schema: Mapping, registry: Mapping[str, Mapping] | None = None) -> None:
        self.schema = schema
        self.registry = dict(registry or {})
        if "$id" in schema:
            self.registry.setdefault(schema["$id"], schema)
        for doc in self.registry.values():
            _check_keywords(doc)
        self._compiled: dict[int, Any] = {}
        self._run = self._compile(schema, schema)

    def validate(self, instance: Any) -> None:
        """Raise :class:`SchemaViolation` at the first violation."""
        self._run(instance, None)

    def _resolve(self, ref: str, doc: Mapping) -> tuple[Mapping, Mapping]:
        base, _, fragment = ref.partition("#")
        if base:
            doc = self.registry[base]
        node: Any = doc
        for part in [p for p in fragment.split("/") if p]:
            node = node[part.replace("~1", "/").replace("~0", "~")]
        return node, doc

    def _compile(self, schema: Mapping, doc: Mapping):
        key = id(schema)
        if key in self._compiled:
            return self._compiled[key]
        checks: list = []

        def run(value: Any, path: tuple | None) -> None:
            kind = type(value)
            if kind is float:
                if value != value or value == _INF or value == -_INF:
                    _fail(path, f"{value!r} is not allowed (numbers must be finite)")
            elif kind is NonFinite:
                _fail(path, f"{value.text} is not allowed (numbers must be finite)")
            for check in checks:
                check(value, path)

        self._compiled[key] = run
        if "$ref" in schema:
            target, target_doc = self._resolve(schema["$ref"], doc)
            checks.append(self._compile(target, target_doc))
        if "anyOf" in schema:
            checks.append(self._any_of([self._compile(b, doc) for b in schema["anyOf"]]))
        if "type" in schema:
            checks.append(_type_check(schema["type"] if isinstance(schema["type"], list) else [schema["type"]]))
        if "const" in schema:
            const = schema["const"]

            def check_const(value, path):
                if not _same(value, const):
                    _fail(path, f"must be {_short(const)}, got {_short(value)}")
            checks.append(check_const)
        if "enum" in schema:
            options = schema["enum"]

            def check_enum(value, path):
                if not any(_same(value, o) for o in options):
                    _fail(path, f"{_short(value)} is not one of {', '.join(_short(o) for o in options)}",
                          type_mismatch=not all(isinstance(o, type(value)) for o in options))
            checks.append(check_enum)
        numeric = [(k, schema[k]) for k in ("minimum", "maximum") if k in schema]
        if numeric:
            low, high = schema.get("minimum"), schema.get("maximum")

            def check_number(value, path):
                if value.__class__ in (int, float):
                    if low is not None and value < low:
                        _fail(path, f"{_short(value)} is below the minimum {low}")
                    if high is not None and value > high:
                        _fail(path, f"{_short(value)} is above the maximum {high}")
            checks.append(check_number)
        if any(k in schema for k in ("minLength", "maxLength", "pattern")):
            shortest, longest = schema.get("minLength"), schema.get("maxLength")
            pattern = _regex(schema["pattern"]) if "pattern" in schema else None

            def check_string(value, path):
                if value.__class__ is str:
                    if shortest is not None and len(value) < shortest:
                        _fail(path, f"{_short(value)} is shorter than {shortest} characters")
                    if longest is not None and len(value) > longest:
                        _fail(path, f"is {len(value)} characters long, above the limit of {longest}")
                    if pattern is not None and not pattern.search(value):
                        _fail(path, f"{_short(value)} does not match the pattern {pattern.pattern}")
            checks.append(check_string)
        if any(k in schema for k in ("minItems", "maxItems", "items", "uniqueItems")):
            fewest, most = schema.get("minItems"), schema.get("maxItems")
            items = self._compile(schema["items"], doc) if "items" in schema else None
            unique = bool(schema.get("uniqueItems"))

            def check_array(value, path):
                if value.__class__ is list:
                    if fewest is not None and len(value) < fewest:
                        _fail(path, f"has {len(value)} items, fewer than the minimum {fewest}")
                    if most is not None and len(value) > most:
                        _fail(path, f"has {len(value)} items, more than the maximum {most}")
                    if items is not None:
                        for index, item in enumerate(value):
                            items(item, (path, index))
                    if unique:
                        for index, item in enumerate(value):
                            for earlier in range(index):
                                if _same(item, value[earlier]):
                                    where = format_path(path)
                                    raise SchemaViolation(f"{where}[{index}]", f"{_short(item)} repeats {where}[{earlier}]")
            checks.append(check_array)
        object_keys = ("minProperties", "maxProperties", "required", "properties", "additionalProperties", "propertyNames")
        if any(k in schema for k in object_keys):
            fewest, most = schema.get("minProperties"), schema.get("maxProperties")
            required = list(schema.get("required", ()))
            properties = {k: self._compile(v, doc) for k, v in schema.get("properties", {}).items()}
            additional = schema.get("additionalProperties", True)
            extra = self._compile(additional, doc) if isinstance(additional, dict) else None
            closed = additional is False
            names = self._compile(schema["propertyNames"], doc) if "propertyNames" in schema else None

            def check_object(value, path):
                if value.__class__ is not dict:
                    return
                if fewest is not None and len(value) < fewest:
                    _fail(path, f"has {len(value)} fields, fewer than the minimum {fewest}")
                if most is not None and len(value) > most:
                    _fail(path, f"has {len(value)} fields, more than the maximum {most}")
                for name in required:
                    if name not in value:
                        _fail((path, name), "required field is missing")
                for name, item in value.items():
                    if names is not None:
                        try:
                            names(name, (path, name))
                        except SchemaViolation as exc:
                            raise SchemaViolation(exc.path, f"field name {exc.problem}") from None
                    check = properties.get(name)
                    if check is not None:
                        check(item, (path, name))
                    elif closed:
                        _fail((path, name), "unexpected field")
                    elif extra is not None:
                        extra(item, (path, name))
            checks.append(check_object)
        return run

    @staticmethod
    def _any_of(branches: list):
        def check_any_of(value, path):
            errors = []
            for branch in branches:
                try:
                    branch(value, path)
                    return
                except SchemaViolation as exc:
                    errors.append(exc)
            specific = [e for e in errors if not e.type_mismatch]
            if specific:
                raise specific[0]
            wanted = " or ".join(dict.fromkeys(e.problem.split(", got ")[0].removeprefix("expected ") for e in errors))
            _fail(path, f"expected {wanted}, got {json_type(value)}", type_mismatch=True)
        return check_any_of


def _type_check(types: list[str]):
    for name in types:
        _is_type(None, name)  # unknown names raise here, at compile time
    label = " or ".join(types)

    def check_type(value, path):
        for name in types:
            if _is_type(value, name):
                return
        shown = f" {_short(value)}" if not isinstance(value, (dict, list)) and value is not None else ""
        _fail(path, f"expected {label}, got {json_type(value)}{shown}", type_mismatch=True)
    return check_type


def _check_keywords(schema: Any) -> None:
    """Refuse schemas using keywords this validator does not implement."""
    if isinstance(schema, list):
        for item in schema:
            _check_keywords(item)
        return
    if not isinstance(schema, Mapping):
        return
    unknown = set(schema) - _ANNOTATIONS - _IMPLEMENTED
    if unknown:
        raise ValueError(f"schema keyword(s) {sorted(unknown)} not supported by frbench's validator")
    for key, sub in schema.items():
        if key in ("properties", "$defs"):
            for child in sub.values():
                _check_keywords(child)
        elif key in ("items", "additionalProperties", "propertyNames"):
            _check_keywords(sub)
        elif key == "anyOf":
            _check_keywords(sub)
