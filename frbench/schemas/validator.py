"""JSON Schema (draft 2020-12) validation of frbench's files with the ``jsonschema`` library.

:class:`Validator` wraps :class:`jsonschema.Draft202012Validator` and turns its
most relevant error (the library's ``relevance`` ranking, as in ``best_match``) into one line,
``path: problem``, with a path such as ``cells[3].success_rate``. Two things
happen around the library:

* Non-finite numbers are refused everywhere, before the schema is applied:
  Python's ``json`` reads ``NaN``/``Infinity`` unless told otherwise, so
  frbench's readers turn them into :class:`NonFinite` markers
  (``parse_constant=NonFinite``) and :func:`find_non_finite` names the first
  field holding one (or a float ``nan``/``inf`` built in Python).
* Local and cross-file ``$ref`` are resolved once, when the validator is built
  (:func:`inline_refs`): the schemas are not recursive, and a results file of
  6720 episodes then validates in 0.7 s instead of 1.6 s (each ``$ref`` costs
  the library a registry lookup per value).
"""

from __future__ import annotations

import math
import re
from typing import Any, Iterator, Mapping

import jsonschema
from jsonschema.exceptions import ValidationError, relevance

from frbench.errors import ResultsError

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

    def __init__(self, path: str, problem: str) -> None:
        self.path = path
        self.problem = problem
        super().__init__(f"{path or '(top level)'}: {problem}")


def join_path(path: str, key: str | int) -> str:
    """``cells`` + 3 -> ``cells[3]``; ``robots`` + ``go2`` -> ``robots.go2``; odd keys are quoted."""
    if isinstance(key, int):
        return f"{path}[{key}]"
    if _KEY.match(key):
        return f"{path}.{key}" if path else key
    return f"{path}[{_short(key)}]"


def format_path(keys) -> str:
    """A sequence of object keys and array indices -> ``cells[3].success_rate``."""
    text = ""
    for key in keys:
        text = join_path(text, key)
    return text


def _short(value: Any, limit: int = 60) -> str:
    """A one-line, bounded rendering of a value for messages."""
    if isinstance(value, NonFinite):
        return value.text
    if isinstance(value, (dict, list)):
        return f"a JSON {'object' if isinstance(value, dict) else 'array'}"
    if value is None:
        text = "null"
    elif isinstance(value, bool):
        text = "true" if value else "false"
    else:
        text = repr(value)
    text = text.encode("ascii", "backslashreplace").decode()
    return text if len(text) <= limit else text[: limit - 4] + "...'"


def json_type(value: Any) -> str:
    """The JSON type name of a parsed value."""
    for kind, name in ((bool, "boolean"), (int, "integer"), (float, "number"), (str, "string"),
                       (list, "array"), (dict, "object"), (NonFinite, "non-finite number")):
        if isinstance(value, kind):
            return name
    return "null" if value is None else type(value).__name__


def _same(a: Any, b: Any) -> bool:
    """JSON equality: 1 == 1.0, but true != 1 and "1" != 1."""
    if isinstance(a, bool) or isinstance(b, bool):
        return type(a) is type(b) and a == b
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    return a == b and (type(a) is type(b) or {type(a), type(b)} <= {int, float})


def find_non_finite(instance: Any) -> SchemaViolation | None:
    """The first ``NaN``/``Infinity`` (a :class:`NonFinite` marker or a float) in document order, as a violation."""
    stack: list[tuple[Any, tuple]] = [(instance, ())]
    while stack:
        value, keys = stack.pop()
        if isinstance(value, dict):
            stack.extend((item, keys + (key,)) for key, item in reversed(list(value.items())))
        elif isinstance(value, list):
            stack.extend((item, keys + (index,)) for index, item in reversed(list(enumerate(value))))
        elif isinstance(value, NonFinite) or (isinstance(value, float) and not math.isfinite(value)):
            return SchemaViolation(format_path(keys), f"{_short(value)} is not allowed (numbers must be finite)")
    return None


def inline_refs(node: Any, document: Mapping, registry: Mapping[str, Mapping]) -> Any:
    """``node`` with every ``$ref`` replaced by its target (``$defs`` dropped); a ``$ref`` beside other
    keywords becomes ``allOf: [target]`` next to them. The schemas must not be recursive."""
    if isinstance(node, list):
        return [inline_refs(item, document, registry) for item in node]
    if not isinstance(node, Mapping):
        return node
    out = {key: inline_refs(value, document, registry) for key, value in node.items() if key not in ("$ref", "$defs")}
    if "$ref" not in node:
        return out
    base, _, fragment = node["$ref"].partition("#")
    target_doc = registry[base] if base else document
    target: Any = target_doc
    for part in [p for p in fragment.split("/") if p]:
        target = target[part.replace("~1", "/").replace("~0", "~")]
    resolved = inline_refs(target, target_doc, registry)
    keywords = {key: value for key, value in out.items() if key not in ("$schema", "$id", "title", "description")}
    return {**out, "allOf": [resolved]} if keywords else resolved


def _problem(error: ValidationError) -> tuple[list, str]:
    """(path keys, problem) of one library error, in frbench's words."""
    keys, value, kind, limit = list(error.absolute_path), error.instance, error.validator, error.validator_value
    if kind == "required":
        missing = next(name for name in limit if name not in value)
        return keys + [missing], "required field is missing"
    if kind == "additionalProperties":
        known = error.schema.get("properties", {})
        extra = next(name for name in value if name not in known)
        return keys + [extra], "unexpected field"
    if kind == "type":
        types = limit if isinstance(limit, list) else [limit]
        shown = f" {_short(value)}" if not isinstance(value, (dict, list)) and value is not None else ""
        return keys, f"expected {' or '.join(types)}, got {json_type(value)}{shown}"
    if kind == "anyOf":
        specific = [e for e in error.context if e.validator != "type"]
        if specific:
            return _problem(_pick(specific))
        wanted = dict.fromkeys(t for e in error.context for t in (e.validator_value if isinstance(e.validator_value, list) else [e.validator_value]))
        return keys, f"expected {' or '.join(wanted)}, got {json_type(value)}"
    if kind == "uniqueItems":
        for index, item in enumerate(value):
            for earlier in range(index):
                if _same(item, value[earlier]):
                    return keys + [index], f"{_short(item)} repeats {format_path(keys + [earlier])}"
    messages = {
        "const": lambda: f"must be {_short(limit)}, got {_short(value)}",
        "enum": lambda: f"{_short(value)} is not one of {', '.join(_short(o) for o in limit)}",
        "minimum": lambda: f"{_short(value)} is below the minimum {limit}",
        "maximum": lambda: f"{_short(value)} is above the maximum {limit}",
        "minLength": lambda: f"{_short(value)} is shorter than {limit} characters",
        "maxLength": lambda: f"is {len(value)} characters long, above the limit of {limit}",
        "pattern": lambda: f"{_short(value)} does not match the pattern {limit}",
        "minItems": lambda: f"has {len(value)} items, fewer than the minimum {limit}",
        "maxItems": lambda: f"has {len(value)} items, more than the maximum {limit}",
        "minProperties": lambda: f"has {len(value)} fields, fewer than the minimum {limit}",
        "maxProperties": lambda: f"has {len(value)} fields, more than the maximum {limit}",
    }
    return keys, messages[kind]() if kind in messages else error.message


def _pick(errors) -> ValidationError:
    """The most relevant error by the library's ranking (:data:`jsonschema.exceptions.relevance`, the key of
    ``best_match``), without descending into ``anyOf``: :func:`_problem` words those from their branches."""
    return max(errors, key=relevance)


def _from_property_name(error: ValidationError) -> bool:
    return "propertyNames" in error.absolute_schema_path


def violation(error: ValidationError) -> SchemaViolation:
    """One library error as a :class:`SchemaViolation`; an error in a field's name names that field."""
    keys, problem = _problem(error)
    if _from_property_name(error):
        return SchemaViolation(format_path(list(error.absolute_path) + [error.instance]), f"field name {problem}")
    return SchemaViolation(format_path(keys), problem)


class Validator:
    """Validates instances against a schema; ``registry`` maps ``$id`` to schemas for cross-file ``$ref``."""

    def __init__(self, schema: Mapping, registry: Mapping[str, Mapping] | None = None) -> None:
        registry = dict(registry or {})
        if "$id" in schema:
            registry.setdefault(schema["$id"], schema)
        for document in registry.values():
            jsonschema.Draft202012Validator.check_schema(document)
        self.schema = schema
        self._library = jsonschema.Draft202012Validator(inline_refs(schema, schema, registry))

    def errors(self, instance: Any) -> Iterator[ValidationError]:
        """Every error the library finds (non-finite numbers are checked by :meth:`validate`)."""
        return self._library.iter_errors(instance)

    def validate(self, instance: Any) -> None:
        """Raise :class:`SchemaViolation` for a non-finite number, else for the library's best error."""
        non_finite = find_non_finite(instance)
        if non_finite is not None:
            raise non_finite
        if self._library.is_valid(instance):
            return
        raise violation(_pick(self.errors(instance)))
