"""A small JSON Schema checker for the subset of keywords xnlos's own schemas use.

Why hand-written: the ``jsonschema`` package is not a dependency of xnlos (nor installed in its
environment), and the results schema needs only a dozen keywords. The subset is plain JSON Schema
(draft 2020-12), so any full validator accepts the same schemas; a keyword outside it is refused
(:class:`SchemaKeywordError`) rather than silently ignored, so a schema cannot promise a check this
module does not make.

Supported: type (a name or a list), enum, const, minimum, maximum, properties, required,
additionalProperties (bool or schema), items, minItems, maxItems; annotations $schema, $id, title,
description, $comment are ignored.
"""
from __future__ import annotations

from typing import Any

from xnlos_core.errors import SchemaKeywordError, SchemaViolation

KEYWORDS = {"type", "enum", "const", "minimum", "maximum", "properties", "required", "additionalProperties",
            "items", "minItems", "maxItems"}
ANNOTATIONS = {"$schema", "$id", "title", "description", "$comment"}


def _is_type(value: Any, name: str) -> bool:
    if name == "null":
        return value is None
    if name == "boolean":
        return isinstance(value, bool)
    if name == "integer":
        return (isinstance(value, int) and not isinstance(value, bool)) or (
            isinstance(value, float) and value.is_integer())
    if name == "number":
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if name == "string":
        return isinstance(value, str)
    if name == "array":
        return isinstance(value, list)
    if name == "object":
        return isinstance(value, dict)
    raise SchemaKeywordError(f"type: unknown JSON type {name!r}")


def _type_name(value: Any) -> str:
    for name in ("null", "boolean", "integer", "number", "string", "array", "object"):
        if _is_type(value, name):
            return name
    return type(value).__name__


def _join(path: str, key: str | int) -> str:
    return f"{path}[{key}]" if isinstance(key, int) else (f"{path}.{key}" if path else str(key))


def check(value: Any, schema: dict[str, Any], path: str = "") -> None:
    """Raise :class:`SchemaViolation` at the first place where ``value`` breaks ``schema``
    (depth first, keys in schema order)."""
    unknown = set(schema) - KEYWORDS - ANNOTATIONS
    if unknown:
        raise SchemaKeywordError(f"schema at {path or '<root>'}: unsupported keyword(s) {sorted(unknown)}; "
                                 f"this checker implements {sorted(KEYWORDS)}")
    if "type" in schema:
        types = [schema["type"]] if isinstance(schema["type"], str) else schema["type"]
        if not any(_is_type(value, t) for t in types):
            raise SchemaViolation(path, f"expected {' or '.join(types)}, got {_type_name(value)} {str(value)[:60]}")
    if "const" in schema and value != schema["const"]:
        raise SchemaViolation(path, f"expected {schema['const']!r}, got {value!r}")
    if "enum" in schema and value not in schema["enum"]:
        raise SchemaViolation(path, f"expected one of {schema['enum']}, got {value!r}")
    if _is_type(value, "number"):
        if "minimum" in schema and value < schema["minimum"]:
            raise SchemaViolation(path, f"expected ≥ {schema['minimum']}, got {value}")
        if "maximum" in schema and value > schema["maximum"]:
            raise SchemaViolation(path, f"expected ≤ {schema['maximum']}, got {value}")
    if isinstance(value, dict):
        _check_object(value, schema, path)
    if isinstance(value, list):
        _check_array(value, schema, path)


def _check_object(value: dict, schema: dict, path: str) -> None:
    for key in schema.get("required", ()):
        if key not in value:
            raise SchemaViolation(_join(path, key), "required key missing")
    props = schema.get("properties", {})
    extra = schema.get("additionalProperties", True)
    for key, v in value.items():
        if key in props:
            check(v, props[key], _join(path, key))
        elif extra is False:
            raise SchemaViolation(_join(path, key), f"unexpected key (allowed: {', '.join(sorted(props))})")
        elif isinstance(extra, dict):
            check(v, extra, _join(path, key))


def _check_array(value: list, schema: dict, path: str) -> None:
    if "minItems" in schema and len(value) < schema["minItems"]:
        raise SchemaViolation(path, f"expected at least {schema['minItems']} items, got {len(value)}")
    if "maxItems" in schema and len(value) > schema["maxItems"]:
        raise SchemaViolation(path, f"expected at most {schema['maxItems']} items, got {len(value)}")
    if "items" in schema:
        for i, v in enumerate(value):
            check(v, schema["items"], _join(path, i))


def check_schema(schema: dict[str, Any], path: str = "<root>") -> None:
    """Raise :class:`SchemaKeywordError` if ``schema`` or any schema nested in it uses a keyword
    outside the supported subset (:func:`check` only meets the parts a value reaches)."""
    if not isinstance(schema, dict):
        raise SchemaKeywordError(f"schema at {path}: expected an object, got {type(schema).__name__}")
    unknown = set(schema) - KEYWORDS - ANNOTATIONS
    if unknown:
        raise SchemaKeywordError(f"schema at {path}: unsupported keyword(s) {sorted(unknown)}")
    for key, sub in schema.get("properties", {}).items():
        check_schema(sub, f"{path}.properties.{key}")
    for key in ("items", "additionalProperties"):
        if isinstance(schema.get(key), dict):
            check_schema(schema[key], f"{path}.{key}")
