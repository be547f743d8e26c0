"""Strict JSON for every file and print-out of the project: an infinite number is the string "inf", an undefined
one null, -0.0 is 0.0 (docs/contracts.md, "Command line")."""

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


def json_safe(obj):
    """``obj`` (dicts, lists, tuples, numpy arrays and scalars) with every float made strict JSON by
    :func:`_json_number`: what every JSON the project writes goes through (``json.dumps(..., allow_nan=False)``
    then holds)."""
    if isinstance(obj, dict):
        return {k: json_safe(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [json_safe(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return json_safe(obj.tolist())
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return _json_number(obj)
    return obj
