"""Schema validation of YAML inputs (robot files and the config) with one clear message per error.

The JSON schemas are package data in ``src/stiffcal/schemas/`` (so an installed wheel has them);
``workflow/schemas`` is a link to that directory for the workflow's conventional layout.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from .errors import InputError

SCHEMA_DIR = Path(__file__).resolve().parent / "schemas"


def load_schema(name: str) -> dict:
    """Return the parsed schema ``workflow/schemas/<name>.schema.yaml``."""
    import yaml

    with open(SCHEMA_DIR / f"{name}.schema.yaml", encoding="utf-8") as fh:
        return yaml.safe_load(fh)


def read_yaml(path: str | Path) -> Any:
    """Parse a YAML file; a missing file or a syntax error becomes an :class:`InputError`."""
    import yaml

    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as err:
        raise InputError(f"cannot read file ({err.strerror})", source=str(path)) from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        raise InputError(f"not valid YAML{where}: {getattr(err, 'problem', err)}", source=str(path)) from None


def json_path(parts) -> str:
    """``['links_m', 1]`` -> ``links_m[1]``; the field name used in error messages."""
    out = ""
    for p in parts:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out or "<top level>"


def validate(document: Any, schema_name: str, source: str) -> None:
    """Validate ``document`` against a named schema; raise one :class:`InputError` for the first error.

    The error is the deepest, most specific one (jsonschema's ``best_match``), e.g.
    ``robot.yaml: field 'links_m[1]': expected a number > 0, got -0.4``.
    """
    import jsonschema

    schema = load_schema(schema_name)
    validator = jsonschema.Draft202012Validator(schema)
    error = jsonschema.exceptions.best_match(validator.iter_errors(document))
    if error is None:
        return
    raise InputError(_explain(error), source=source, field=json_path(error.absolute_path))


def _explain(error) -> str:
    """Turn a jsonschema error into 'expected ..., got ...' wording."""
    v = error.validator_value
    got = f"got {error.instance!r}"
    if error.validator == "required":
        missing = [k for k in v if k not in error.instance]
        return f"missing required field(s) {', '.join(repr(k) for k in missing)}"
    if error.validator == "additionalProperties":
        extra = sorted(set(error.instance) - set(error.schema.get("properties", {})))
        allowed = ", ".join(sorted(error.schema.get("properties", {})))
        return f"unknown field(s) {', '.join(repr(k) for k in extra)}; allowed: {allowed}"
    if error.validator == "enum":
        return f"expected one of {', '.join(repr(x) for x in v)}, {got}"
    if error.validator == "type":
        return f"expected {v if isinstance(v, str) else ' or '.join(v)}, {got}"
    if error.validator == "exclusiveMinimum":
        return f"expected a number > {v}, {got}"
    if error.validator == "minimum":
        return f"expected a number >= {v}, {got}"
    if error.validator == "maximum":
        return f"expected a number <= {v}, {got}"
    if error.validator in ("minItems", "maxItems"):
        return f"expected {'at least' if error.validator == 'minItems' else 'at most'} {v} item(s), {got}"
    return error.message
