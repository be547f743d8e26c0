"""The input layer for YAML files (robot files and the config): a safe loader and schema validation, with
one clear, bounded message per error naming the file and the field.

:func:`read_yaml` reads text that people write by hand, and possibly hostile text, safely:

* the file must be a regular file (a FIFO, a device or a directory is refused without reading it), UTF-8 and
  at most :data:`MAX_BYTES` long;
* the YAML is parsed with PyYAML's safe loader, changed to read scalars as YAML 1.2 (core schema) does:
  ``1e-6`` and ``.5`` are numbers (YAML 1.1 reads ``1e-6`` as a string), ``010`` is ten, ``yes``/``no``
  are strings, ``1:30`` is a string;
* a repeated key in a mapping, an anchor or alias (``&a``/``*a``: a kilobyte of aliases can expand to
  gigabytes), and nesting deeper than :data:`MAX_DEPTH` are refused;
* every number must be finite (``.nan`` and ``.inf`` are refused with the field named).

The JSON schemas are package data in ``src/stiffcal/schemas/`` (so an installed wheel has them);
``workflow/schemas`` is a link to that directory for the workflow's conventional layout. A schema node
``x-registry: NAME`` takes its ``enum`` (the keys in the registry's order), and ``x-registry-default: NAME`` its
``default``, from a registry of :data:`REGISTRIES`, so that a new entry of the registry needs no schema edit.
"""

from __future__ import annotations

import copy
import functools
import math
import re
from pathlib import Path
from typing import Any

from .errors import InputError, short_repr

SCHEMA_DIR = Path(__file__).resolve().parent / "schemas"
#: largest YAML file accepted [bytes]
MAX_BYTES = 1_000_000
#: deepest nesting of lists and mappings accepted
MAX_DEPTH = 20
#: the registries a schema can take an ``enum`` or a ``default`` from: name -> (module, attribute holding the keys,
#: attribute holding the default)
REGISTRIES = {"criteria": ("stiffcal.model.criteria", "CRITERIA_KEYS", "STUDY_DEFAULT")}


def load_schema(name: str) -> dict:
    """Return the parsed schema ``src/stiffcal/schemas/<name>.schema.yaml`` (a copy of the one parsed at the first
    call: a study reads its robot file once per M)."""
    return copy.deepcopy(_parsed_schema(name))


@functools.lru_cache(maxsize=None)
def _parsed_schema(name: str) -> dict:
    return _with_registries(_parse((SCHEMA_DIR / f"{name}.schema.yaml").read_text(encoding="utf-8"),
                                   str(SCHEMA_DIR / name)))


def _registry_keys(name: str, default: bool = False) -> list[str]:
    import importlib

    module, keys, default_keys = REGISTRIES[name]
    return list(getattr(importlib.import_module(module), default_keys if default else keys))


def _with_registries(node: Any) -> Any:
    """``node`` with every ``x-registry`` / ``x-registry-default`` resolved (module docstring), recursively."""
    if isinstance(node, list):
        return [_with_registries(v) for v in node]
    if not isinstance(node, dict):
        return node
    out = {k: _with_registries(v) for k, v in node.items() if k not in ("x-registry", "x-registry-default")}
    if "x-registry" in node:
        out["enum"] = _registry_keys(node["x-registry"])
    if "x-registry-default" in node:
        out["default"] = _registry_keys(node["x-registry-default"], default=True)
    return out


_INT = re.compile(r"^(?:[-+]?[0-9]+|0o[0-7]+|0x[0-9a-fA-F]+)$")
_FLOAT = re.compile(r"^(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?"
                    r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$")
_BOOL = re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$")
_NULL = re.compile(r"^(?:~|null|Null|NULL|)$")


def _loader(source: str):
    """A PyYAML safe loader class reading the YAML 1.2 core schema, refusing aliases, anchors, repeated keys
    and deep nesting (module docstring). Errors are :class:`InputError` naming ``source``."""
    import yaml

    class Loader(yaml.SafeLoader):
        yaml_implicit_resolvers: dict = {}
        depth = 0

        def compose_node(self, parent, index):
            event = self.peek_event()
            if isinstance(event, yaml.AliasEvent) or getattr(event, "anchor", None):
                raise InputError("YAML anchors and aliases (&name, *name) are not allowed (line "
                                 f"{event.start_mark.line + 1})", source=source)
            self.depth += 1
            if self.depth > MAX_DEPTH:
                raise InputError(f"nested deeper than {MAX_DEPTH} levels (line {event.start_mark.line + 1})",
                                 source=source)
            try:
                return super().compose_node(parent, index)
            finally:
                self.depth -= 1

        def construct_mapping(self, node, deep=False):
            seen = {}
            for key_node, _ in node.value:
                key = self.construct_object(key_node, deep=True)
                line = key_node.start_mark.line + 1
                try:
                    if key in seen:
                        raise InputError(f"key {short_repr(key)} appears twice (lines {seen[key]} and {line}); keep "
                                         "one", source=source)
                    seen[key] = line
                except TypeError:
                    raise InputError(f"a key that is a list or a mapping (line {line})", source=source) from None
            return super().construct_mapping(node, deep)

    def construct_int(loader, node):
        v = loader.construct_scalar(node).replace("_", "")
        return int(v[2:], 8) if v.startswith("0o") else int(v, 16) if v.startswith("0x") else int(v, 10)

    def construct_float(loader, node):
        v = loader.construct_scalar(node).lower()
        return float(v.replace(".inf", "inf").replace(".nan", "nan")) if "inf" in v or "nan" in v else float(v)

    for tag, pattern, first in (("bool", _BOOL, "tTfF"), ("int", _INT, "-+0123456789"),
                                ("float", _FLOAT, "-+0123456789."), ("null", _NULL, ["~", "n", "N", ""])):
        Loader.add_implicit_resolver(f"tag:yaml.org,2002:{tag}", pattern, list(first))
    # not resolved implicitly (YAML 1.2 core schema): '<<' merge keys, dates and '=' stay strings
    Loader.add_constructor("tag:yaml.org,2002:int", construct_int)
    Loader.add_constructor("tag:yaml.org,2002:float", construct_float)
    return Loader


def _parse(text: str, source: str) -> Any:
    import yaml

    try:
        return yaml.load(text, Loader=_loader(source))  # noqa: S506 - a SafeLoader subclass
    except yaml.YAMLError as err:
        mark = getattr(err, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        raise InputError(f"not valid YAML{where}: {getattr(err, 'problem', None) or err}", source=source) from None
    except RecursionError:
        raise InputError(f"nested deeper than {MAX_DEPTH} levels", source=source) from None


def check_finite(document: Any, source: str, path: tuple = ()) -> None:
    """Refuse NaN and infinite numbers anywhere in a parsed document, naming the field."""
    if isinstance(document, float) and not math.isfinite(document):
        raise InputError(f"expected a finite number, got {document}", source=source, field=json_path(path))
    if isinstance(document, dict):
        for k, v in document.items():
            check_finite(v, source, (*path, k))
    elif isinstance(document, list):
        for i, v in enumerate(document):
            check_finite(v, source, (*path, i))


def read_yaml(path: str | Path) -> Any:
    """Parse a YAML file safely (module docstring); every problem is an :class:`InputError` naming the file."""
    from .safeio import file_kind, read_bounded

    path = Path(path)
    try:
        kind = file_kind(path.stat().st_mode)
    except OSError as err:
        raise InputError(f"cannot read file ({err.strerror})", source=str(path)) from None
    if kind:  # a FIFO would block the read forever, a directory is no YAML file
        raise InputError(f"expected a YAML file, but it is {kind}: refused without reading it", source=str(path))
    raw = read_bounded(path, MAX_BYTES, what="YAML file")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as err:
        raise InputError(f"not UTF-8 text (byte 0x{raw[err.start]:02x} at offset {err.start}); save the file as "
                         "UTF-8", source=str(path)) from None
    doc = _parse(text, str(path))
    check_finite(doc, str(path))
    return doc


def json_path(parts) -> str:
    """``['links_m', 1]`` -> ``links_m[1]``; the field name used in error messages."""
    out = ""
    for p in parts:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out or "<top level>"


def validate(document: Any, schema_name: str, source: str, prefix: str = "") -> None:
    """Validate ``document`` against a named schema; raise one :class:`InputError` for the first error.

    The error is the deepest, most specific one (jsonschema's ``best_match``), e.g.
    ``robot.yaml: field 'links_m[1]': expected a number > 0, got -0.4``; ``prefix`` names where the document
    sits in its file (a cell mapping under ``cell``: ``cell.clearance_m``).
    """
    import jsonschema

    check_finite(document, source, (prefix,) if prefix else ())
    schema = load_schema(schema_name)
    validator = jsonschema.Draft202012Validator(schema)
    error = jsonschema.exceptions.best_match(validator.iter_errors(document))
    if error is None:
        return
    if error.validator == "required" and not error.absolute_path:  # keys the document's own schema knows are no
        error.schema = {**error.schema, "properties": {**schema.get("properties", {}),  # typos (a sub-schema's
                                                       **error.schema.get("properties", {})}}  # 'required' knows few)
    where = json_path(error.absolute_path)
    if prefix:
        where = prefix if where == "<top level>" else prefix + ("" if where.startswith("[") else ".") + where
    raise InputError(_explain(error), source=source, field=where)


def _spelling(given: list[str], expected: list[str]) -> str:
    """' (did you mean ...?)' for the given keys that look like misspellings of expected ones (difflib), else ''."""
    import difflib

    best: dict[str, tuple[float, str]] = {}  # per expected key, the given key most like it (a fresh user's typo
    for g in given:                          # 'tip_fram' was matched and so was their correct 'base_frame')
        for e in difflib.get_close_matches(g, expected, n=1, cutoff=0.6):
            ratio = difflib.SequenceMatcher(None, g, e).ratio()
            if ratio > best.get(e, (0.0, ""))[0]:
                best[e] = (ratio, g)
    pairs = sorted((g, e) for e, (_, g) in best.items())
    return f" ({'; '.join(f'{g!r}: did you mean {e!r}?' for g, e in pairs)})" if pairs else ""


def _metres_hint(error) -> str:
    """A length in metres (a field named ``*_m``) beyond its bound that a thousandth of it would meet: millimetres
    given as metres (a fresh user's table of 900 x 1200 x 750; another's clearance of 20 against a bound of 10)."""
    names = [str(k) for k in error.absolute_path if isinstance(k, str)]
    if not names or not names[-1].endswith("_m") or isinstance(error.instance, bool):
        return ""
    bound, value = float(error.validator_value), float(error.instance) / 1000.0
    if (value <= bound) if error.validator == "maximum" else (value >= bound):
        return f": {names[-1]} is in metres; millimetres given as metres? (divide by 1000)"
    return ""


def _explain(error) -> str:
    """Turn a jsonschema error into 'expected ..., got ...' wording (the value shown is cut to a few dozen
    characters)."""
    v = error.validator_value
    got = f"got {short_repr(error.instance)}"
    if error.validator == "required":
        missing = [k for k in v if k not in error.instance]
        extra = [str(k) for k in error.instance if str(k) not in error.schema.get("properties", {})]
        return f"missing required field(s) {', '.join(repr(k) for k in missing)}" + _spelling(extra, missing)
    if error.validator == "additionalProperties":
        known = sorted(error.schema.get("properties", {}))
        extra = sorted(map(str, set(error.instance) - set(known)))
        names = ", ".join(repr(k) for k in extra)
        return (f"unknown field(s) {names if len(names) <= 80 else names[:77] + '...'}"
                f"{_spelling(extra, known)}; allowed: {', '.join(known)}")
    if error.validator == "enum":
        return f"expected one of {', '.join(repr(x) for x in v)}, {got}"
    if error.validator == "type":
        return f"expected {v if isinstance(v, str) else ' or '.join(v)}, {got}"
    if error.validator == "exclusiveMinimum":
        return f"expected a number > {v}, {got}"
    if error.validator == "exclusiveMaximum":
        return f"expected a number < {v}, {got}"
    if error.validator in ("minimum", "maximum"):
        return (f"expected a number {'>=' if error.validator == 'minimum' else '<='} {v}, {got}"
                + _metres_hint(error))
    if error.validator in ("minItems", "maxItems"):
        return f"expected {'at least' if error.validator == 'minItems' else 'at most'} {v} item(s), {got}"
    if error.validator == "uniqueItems":
        return f"expected no repeated items, {got}"
    return short_repr(error.message, 200)
