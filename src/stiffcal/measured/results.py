"""The measured-data path's typed results: :class:`Verdict` (docs/measured-data.md, "The verdict") and
:class:`DiscriminationPlan` (docs/measured-data.md, "The next experiment").

Each is what the Python API returns and what its JSON file holds (``verdict.json``, ``plan.json``): one field per
documented key (a test checks the two lists are the same), ``to_dict()`` the JSON object, key for key in the
file's order. Each is also a read-only mapping (``verdict["cause"]``), so code written against the JSON reads it
unchanged; ``json.dumps`` takes ``to_dict()``.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields


class _Record(Mapping):
    """A read-only mapping over a dataclass's fields in :meth:`keys_in_order` (default: declaration order), equal
    to its :meth:`to_dict`."""

    def keys_in_order(self) -> tuple[str, ...]:
        return tuple(f.name for f in fields(self))

    def to_dict(self) -> dict:
        """The JSON object of the file (a plain dict; ``json.dumps(r.to_dict(), allow_nan=False)``)."""
        return {k: getattr(self, k) for k in self.keys_in_order()}

    def __getitem__(self, key: str):
        if key not in self.keys_in_order():
            raise KeyError(key)
        return getattr(self, key)

    def __iter__(self):
        return iter(self.keys_in_order())

    def __len__(self) -> int:
        return len(self.keys_in_order())


#: the fields of the files analysed and of the calibrated model, around the analysis's own
_FILES_FIRST = ("data", "robot")
_FILES_LAST = ("next_round", "machining_path", "calibrated_model")


@dataclass(frozen=True, eq=False, repr=False)  # equality of a Mapping: equal to its to_dict()
class Verdict(_Record):
    """The verdict of one measured data set; every field as documented in docs/measured-data.md ("The verdict"),
    in SI units ([m], [rad], [N], [N m]); JSON types: lists, dicts, strings, numbers, None (never NaN or inf).

    Of the analysis (:func:`stiffcal.measured.discrepancy.verdict_of`): cause, causes, indistinguishable_from,
    equivalent_combinations, p_value, p_value_of, p_value_statement, alpha, structure, nominal, tests,
    lack_of_fit_adjusted_p, absorbed_by_nominal, outlier_rows, separation, zero_point, error_model, notes,
    diagnostics, extended, held_out, gain, residual_structure (None but for ``unexplained``). Of the files and the
    calibrated model (:func:`stiffcal.measured.discrepancy.complete`): data, robot, next_round, machining_path,
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
        middle = [n for n in names if n not in _FILES_FIRST + _FILES_LAST]
        return (*_FILES_FIRST, *middle, *_FILES_LAST)

    def __repr__(self) -> str:  # the headline (the whole verdict: to_dict())
        return (f"Verdict(cause={self.cause!r}, causes={self.causes!r}, p_value={self.p_value:.3g}, "
                f"alpha={self.alpha!r}, n_rows={self.structure.get('n_rows')!r}, notes={len(self.notes)})")


@dataclass(frozen=True, eq=False, repr=False)
class DiscriminationPlan(_Record):
    """The next experiment that tells a verdict's rival causes apart (``plan.json``; every field as documented in
    docs/measured-data.md, "The next experiment"; :func:`stiffcal.measured.discrimination.planned`): the files and
    settings (robot, data, alpha, sigma_m [m], noise_df, experiments, repeats, truth_mode, loads), the verdict
    it starts from, the rival models, whether and where they can be separated (separable, separability,
    design_pairs), the plans (plan, compound, ot_plan: poses [deg], loads [N, N m], criteria [m^2], power),
    power_against_m, cell and notes. JSON types only (never NaN or inf)."""
    robot: str
    data: str | None
    alpha: float
    sigma_m: float
    noise_df: int
    experiments: int
    repeats: int
    truth_mode: str
    loads: dict
    verdict: dict
    models: list
    separable: bool | None
    separability: list
    design_pairs: list
    plan: dict | None
    compound: dict | None
    ot_plan: dict | None
    power_against_m: list
    cell: str | None
    notes: list

    def __repr__(self) -> str:
        power = None if self.plan is None else self.plan.get("power")
        return (f"DiscriminationPlan(experiments={self.experiments}, models={[m['causes'] for m in self.models]}, "
                f"separable={self.separable}, power={power!r}, notes={len(self.notes)})")


def documented_fields(kind: type = Verdict) -> tuple[str, ...]:
    """Every field of ``kind`` (:class:`Verdict` or :class:`DiscriminationPlan`), in declaration order (what
    docs/measured-data.md must list)."""
    return tuple(f.name for f in fields(kind))
