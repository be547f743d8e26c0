"""The measured-data analysis's verdict as a typed result (docs/measured-data.md, section "The verdict").

:class:`Verdict` is what :func:`stiffcal.discrepancy.analyse` and :func:`stiffcal.api.analyse_measurements`
return and what ``verdict.json`` holds: one field per documented key (a test checks the two lists are the same),
:meth:`Verdict.to_dict` the JSON object, key for key in the file's order. It is also a read-only mapping
(``verdict["cause"]``), so code written against the JSON reads it unchanged.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields

#: the fields written only when they apply (absent from the JSON when None)
_OPTIONAL = ("residual_structure",)
#: the fields of the files analysed and of the calibrated model, after the analysis's own
_FILES_FIRST = ("data", "robot")
_FILES_LAST = ("next_round", "machining_path", "calibrated_model")


@dataclass(frozen=True, eq=False, repr=False)  # equality and hash of a Mapping: equal to its to_dict()
class Verdict(Mapping):
    """The verdict of one measured data set; every field as documented in docs/measured-data.md ("The verdict"),
    in SI units ([m], [rad], [N], [N m]); JSON types: lists, dicts, strings, numbers, None (never NaN or inf).

    Of the analysis (:func:`stiffcal.discrepancy.verdict_of`): cause, causes, indistinguishable_from,
    equivalent_combinations, p_value, p_value_of, p_value_statement, alpha, structure, nominal, tests,
    lack_of_fit_adjusted_p, absorbed_by_nominal, outlier_rows, separation, zero_point, error_model, notes,
    diagnostics, extended, held_out, gain, residual_structure (only for ``unexplained``). Of the files and the
    calibrated model (:func:`stiffcal.discrepancy.complete`): data, robot, next_round, machining_path,
    calibrated_model (None when not computed or not written)."""
    cause: str
    causes: list
    indistinguishable_from: list
    equivalent_combinations: list
    p_value: float
    p_value_of: list
    p_value_statement: str
    alpha: float
    structure: dict
    nominal: dict
    tests: dict
    lack_of_fit_adjusted_p: float | None
    absorbed_by_nominal: list
    outlier_rows: list
    separation: dict
    zero_point: dict | None
    error_model: dict
    notes: list
    diagnostics: dict
    extended: dict | None
    held_out: dict | None
    gain: dict | None
    residual_structure: dict | None = None
    data: str | None = None
    robot: str | None = None
    next_round: dict | None = None
    machining_path: dict | None = None
    calibrated_model: str | None = None

    def keys_in_order(self) -> tuple[str, ...]:
        """The JSON's keys in the file's order: the input files, the analysis, the calibrated model."""
        names = [f.name for f in fields(self)]
        middle = [n for n in names if n not in _FILES_FIRST + _FILES_LAST
                  and not (n in _OPTIONAL and getattr(self, n) is None)]
        return (*_FILES_FIRST, *middle, *_FILES_LAST)

    def to_dict(self) -> dict:
        """The JSON object of ``verdict.json`` (a plain dict; ``json.dumps(v.to_dict(), allow_nan=False)``)."""
        return {k: getattr(self, k) for k in self.keys_in_order()}

    def __repr__(self) -> str:  # the headline (the whole verdict: to_dict())
        return (f"Verdict(cause={self.cause!r}, causes={self.causes!r}, p_value={self.p_value:.3g}, "
                f"alpha={self.alpha!r}, n_rows={self.structure.get('n_rows')!r}, notes={len(self.notes)})")

    def __getitem__(self, key: str):
        if key not in self.keys_in_order():
            raise KeyError(key)
        return getattr(self, key)

    def __iter__(self):
        return iter(self.keys_in_order())

    def __len__(self) -> int:
        return len(self.keys_in_order())


def documented_fields() -> tuple[str, ...]:
    """Every field of :class:`Verdict`, in declaration order (what docs/measured-data.md must list)."""
    return tuple(f.name for f in fields(Verdict))
