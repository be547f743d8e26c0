"""Strict JSON for every file and print-out of the project, one walk (:func:`json_safe`): an infinite number is the
string "inf", an undefined one null, -0.0 is 0.0 (docs/contracts.md, "Command line"); in the measured-data
analysis's verdict and plan, a number that is not finite is null with a note naming its field."""

from __future__ import annotations

import math

import numpy as np


def _json_number(x: float):
    """JSON has no inf: an infinite value (unidentifiable) is written as the string 'inf' ('-inf'); an undefined
    one (NaN, e.g. inf / inf) as null; -0.0 as 0.0."""
    x = float(x)
    if math.isnan(x):
        return None
    return x + 0.0 if math.isfinite(x) else ("inf" if x > 0 else "-inf")


def json_safe(obj, notes: list[str] | None = None, path: str = ""):
    """``obj`` (dicts, lists, tuples, numpy arrays and scalars) as strict JSON types: what every JSON the project
    writes goes through (``json.dumps(..., allow_nan=False)`` then holds). The one walk of the project's one JSON
    policy; a number that is not finite is written by the rule of the file's contract (docs/contracts.md):

    - ``notes`` None (the design's JSON, predictions, calibrated robot files): :func:`_json_number`, an infinite
      value (a compliance the plan cannot identify, whose variance is infinite) the string 'inf', an undefined one
      null;
    - ``notes`` a list (the verdict and the plan of the measured-data analysis, whose every number is a statistic):
      null, and a note naming the field (``path``) appended to ``notes``: a statistic that cannot be computed on
      these data is left out with a word, never written as NaN or inf. A key ``notes`` is kept as it is.

    Finite floats are returned as Python floats, -0.0 as 0.0."""
    if isinstance(obj, dict):
        return {k: v if notes is not None and k == "notes" else
                json_safe(v, notes, f"{path}.{k}" if path else str(k)) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v, notes, f"{path}[{i}]") for i, v in enumerate(obj)]
    if isinstance(obj, np.ndarray):
        return json_safe(obj.tolist(), notes, path)
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        if notes is None:
            return _json_number(obj)
        if not math.isfinite(obj):
            notes.append(f"{path} cannot be computed on these data (it is not finite) and is left out")
            return None
        return float(obj) + 0.0
    return obj
