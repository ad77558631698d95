"""frbench's JSON Schemas (package data), validated with the ``jsonschema`` library (draft 2020-12).

* ``results-v1.schema.json``: the file ``frbench evaluate`` writes (``schema_version`` 1).
* ``record-v1.schema.json``: a leaderboard record (``record_schema_version`` 1),
  which embeds a results object by ``$ref`` to ``urn:frbench:schema:results:1``.

``leaderboard/schema/`` in the repository holds byte-identical copies for
people and tools outside frbench; ``frbench leaderboard --check`` keeps them in
sync. Use::

    from frbench.schemas import validate
    validate(results, "results-v1")   # raises SchemaViolation("cells[3].success_rate: ...")
"""

from __future__ import annotations

import json
from functools import lru_cache
from importlib import resources
from typing import Any

from frbench.schemas.validator import NonFinite, SchemaViolation, Validator

__all__ = ["NonFinite", "SchemaViolation", "SCHEMA_NAMES", "schema_text", "load_schema", "validate"]

#: Every schema shipped with frbench, by short name (file ``<name>.schema.json``).
SCHEMA_NAMES = ("results-v1", "record-v1")


def schema_text(name: str) -> str:
    """The exact text of a packaged schema file."""
    if name not in SCHEMA_NAMES:
        raise KeyError(f"unknown schema {name!r}; known: {', '.join(SCHEMA_NAMES)}")
    return resources.files(__name__).joinpath(f"{name}.schema.json").read_text(encoding="utf-8")


@lru_cache(maxsize=None)
def load_schema(name: str) -> dict:
    """A packaged schema, parsed (cached; do not mutate)."""
    return json.loads(schema_text(name))


@lru_cache(maxsize=None)
def _validator(name: str) -> Validator:
    registry = {load_schema(n)["$id"]: load_schema(n) for n in SCHEMA_NAMES}
    return Validator(load_schema(name), registry)


def validate(instance: Any, name: str) -> None:
    """Raise :class:`SchemaViolation` (a ``ResultsError``) naming the first field that breaks schema ``name``."""
    _validator(name).validate(instance)
