"""The workflow's config: read with the safe YAML loader and checked completely before any job runs.

``snakemake`` reads ``config/config.yaml``, or instead (never merged with it) the one file given with
``--configfile FILE``, which must then be a complete config; values given with ``--config KEY=VALUE``
override either. :func:`check_config` checks everything a job would otherwise find wrong, so that a bad
config stops the run (and the dry run) at once with one message naming the file and the field, and no job
starts: the schema (types, ranges, unknown keys), every robot file, test poses within the joint limits,
forces with one component per measured coordinate, map grids that divide 180 deg, unique names, plans
that can identify every compliance, and the measured-data CSVs (read as the discrepancy job reads them).
"""

from __future__ import annotations

import copy
import os
from pathlib import Path

import numpy as np

from ..errors import InputError

DEFAULT = "config/config.yaml"


def workflow_config(configfiles, overrides: dict | None = None, root: str | Path = ".",
                    memo_dir: str | Path | None = None) -> tuple[str, dict]:
    """(source, config): the config the workflow runs with. configfiles: the ``--configfile`` arguments (at most
    one; none means :data:`DEFAULT`); overrides: the ``--config`` values. Read with
    :func:`stiffcal.validation.read_yaml` (duplicate keys, aliases, YAML 1.2 numbers) and checked by
    :func:`check_config`; an error names the file (or ``--config``) and the field. Its keys are sorted at every
    level, so that the same config written in another order (results/config.effective.yaml given back) gives
    the rules the same parameters and reruns nothing. memo_dir: where the check remembers the measured-data
    files it has read and found good (:func:`check_config`)."""
    from ..validation import read_yaml

    root_abs = Path(root).resolve()
    files = [str(Path(f).relative_to(root_abs)) if Path(f).is_absolute() and Path(f).is_relative_to(root_abs)
             else str(f) for f in configfiles]
    if len(files) > 1:
        raise InputError(f"expected one --configfile (a complete config that replaces {DEFAULT}), got "
                         f"{len(files)}: {', '.join(files)}", field="--configfile")
    source = files[0] if files else DEFAULT
    config = read_yaml(source if Path(source).is_absolute() else Path(root) / source)
    if not isinstance(config, dict):
        raise InputError("expected a mapping of config keys (docs/contracts.md)", source=source)
    overrides = dict(overrides or {})
    if overrides:
        from snakemake.utils import update_config

        update_config(config, overrides)
    try:
        check_config(config, root, source, memo_dir)
    except InputError as err:
        top = (err.field or "").split(".")[0].split("[")[0]
        if top in overrides:
            raise err.renamed(source="--config") from None
        raise
    check_output_folders(config, root)
    return source, _sorted(fill_defaults(config))


#: the folders the workflow writes into (below the working directory), before the per-name ones
OUTPUT_FOLDERS = ("results/tables", "results/maps", "results/design", "results/studies", "results/discrepancy",
                  "results/archive", "figures/studies", "paper/build", "logs/discrepancy", "logs/discriminate",
                  "logs/maps", "logs/studies")


def output_folders(config: dict) -> list[str]:
    """Every folder the workflow of ``config`` writes into: :data:`OUTPUT_FOLDERS` and one per design study
    (``results/studies/<name>``, ``figures/studies/<name>``), map study (``results/maps/<name>``) and measured data
    set (``results/discrepancy/<name>``)."""
    def names(items):
        return [str(x["name"]) for x in items or [] if isinstance(x, dict) and "name" in x]

    out = list(OUTPUT_FOLDERS)
    out += [f"{top}/{n}" for n in names(config.get("studies")) for top in ("results/studies", "figures/studies")]
    out += [f"results/maps/{n}" for n in names((config.get("maps") or {}).get("studies"))]
    out += [f"results/discrepancy/{n}" for n in names(config.get("measured_data"))]
    return out


def check_output_folders(config: dict, root: str | Path = ".") -> None:
    """Refuse (InputError naming the path) a run whose output folder, or a folder above it, is something else than
    a folder (a file, a FIFO, a broken link): checked before any job runs, so that no job fails half-way."""
    from ..safeio import file_kind

    root = Path(root)
    seen = set()
    for folder in output_folders(config):
        parts = Path(folder).parts
        for k in range(1, len(parts) + 1):
            rel = Path(*parts[:k])
            if rel in seen:
                continue
            seen.add(rel)
            path = root / rel
            if path.is_dir():
                continue
            if not os.path.lexists(path):
                break  # missing: the workflow makes it and everything below
            what = file_kind(path.stat().st_mode) or "a file" if path.exists() else "a broken symbolic link"
            raise InputError(f"expected a folder for the workflow's outputs ({folder}), but it is {what}: move it "
                             "away", source=str(rel))


def _check_data(data: Path, robot, memo) -> None:
    """Read the measured-data file ``data`` for ``robot`` (:func:`stiffcal.measured.measurements.read_measurements`:
    InputError naming the CSV, row and column) unless ``memo`` (a :class:`stiffcal.memo.JsonMemo`, or None)
    holds the fingerprint of these bytes read for this robot; a good file's fingerprint is added to it."""
    import hashlib

    from ..measured.measurements import read_measurements
    from ..memo import NotFingerprintable, feed, feed_file

    key = None
    if memo is not None:
        h = hashlib.sha256()
        try:
            feed_file(h, data)
            feed(h, robot)
            key = h.hexdigest()
        except NotFingerprintable:
            key = None
        if key is not None and memo.read().get(key) is True:
            return
    read_measurements(data, robot)
    if key is not None:
        memo.write({**memo.read(), key: True})


def _sorted(doc):
    if isinstance(doc, dict):
        return {k: _sorted(doc[k]) for k in sorted(doc)}
    return [_sorted(v) for v in doc] if isinstance(doc, list) else doc


def fill_defaults(config: dict) -> dict:
    """``config`` (checked by :func:`check_config`) with every optional key of the schema filled in, in place and
    returned, so that rules and the report's template never meet a missing key: the schema's ``default``,
    the documented derived defaults (``measured_data[].force_N`` and ``moment_Nm``: the study's; its
    ``test_pose_deg`` is left None when not given, :func:`stiffcal.workflow.pipeline._test_pose_rad` resolves it;
    ``studies[].draw_m``: the largest of ``m_values``; ``plans`` and ``measured_data[].discriminate``: every
    default), and None for a key whose documented default is "none" (``moment_Nm``, ``sigma_rad``, a
    ``sigma_m`` estimated from the data, ``plans.pool_step_deg``, ``discriminate.loads``, ``maps``), an empty list
    for ``studies`` and ``measured_data``. A map study's
    ``robot`` / ``link_ratio`` (one of the two) are left as written."""
    from ..validation import load_schema

    schema = load_schema("config")
    _fill(config, schema)
    study = config["study"]
    for entry in config.get("studies") or []:
        if entry["draw_m"] is None:
            entry["draw_m"] = max(entry["m_values"])
    for entry in config.get("measured_data") or []:
        for key in ("force_N", "moment_Nm"):
            if entry[key] is None:
                entry[key] = copy.deepcopy(study[key])
    return config


def _fill(doc, schema: dict) -> None:
    """Fill the defaults of ``schema`` (an object's ``properties``, recursively through arrays) into ``doc``."""
    if isinstance(doc, list) and "items" in schema:
        for item in doc:
            _fill(item, schema["items"])
        return
    if not isinstance(doc, dict) or "properties" not in schema:
        return
    alternatives = {k for alt in schema.get("oneOf", []) for k in alt.get("required", [])}
    for key, sub in schema["properties"].items():
        if key not in doc and key not in schema.get("required", []) and key not in alternatives:
            if "default" in sub:
                doc[key] = copy.deepcopy(sub["default"])
            elif sub.get("type") == "object" and not sub.get("required"):
                doc[key] = {}
            elif sub.get("type") == "array" and sub["items"].get("type") == "object":
                doc[key] = []  # no design studies, no measured data
            else:
                doc[key] = None
        if key in doc:
            _fill(doc[key], sub)



def _check_load_ranges(config: dict, source: str) -> None:
    """Every load of the config within the physical range (:func:`stiffcal.api.check_load`)."""
    from ..api import check_load

    entries = [("study", config["study"])] + [(f"studies[{i}]", e) for i, e in enumerate(config.get("studies") or [])]
    entries += [(f"measured_data[{i}]", e) for i, e in enumerate(config.get("measured_data") or [])]
    for where, entry in entries:
        if entry.get("force_N") is not None:
            try:
                check_load(np.asarray(entry["force_N"], float), np.asarray(entry.get("moment_Nm") or [], float),
                           f"{where}.force_N", f"{where}.moment_Nm")
            except InputError as err:
                raise err.renamed(source=source) from None


def _check_lab_loads(entry: dict, robot, source: str, where: str) -> None:
    """The load set a data set's next experiment may use (``discriminate.loads``), parsed and bounded as the job
    will parse it (:func:`stiffcal.model.loads.load_set`, which :func:`stiffcal.measured.discrimination.load_set`
    calls); the loads of the data need no check."""
    spec = (entry.get("discriminate") or {}).get("loads")
    if spec is None or spec.strip().partition(":")[0] == "data":
        return
    from ..model.loads import load_set
    from ..measured.measurements import FORCE_RESOLUTION_N

    try:
        load_set(spec, robot.task_dim, None, entry.get("force_resolution_N", FORCE_RESOLUTION_N))
    except InputError as err:
        raise err.renamed(f"{where}.discriminate.loads", source) from None


def _check_measured_entry(config: dict, entry: dict, where: str, study, root, source: str, memo) -> None:
    """One entry of ``measured_data`` (``where``): its robot, its data file (read and checked, or known good by
    ``memo``), its lab loads, its noise levels and its test pose and load; InputError naming the field."""
    from ..model.observation import moment_dim
    from ..model.robot import load_config_robot
    from ..planning.study import check_load_bends

    robot = study.robot
    data_robot = load_config_robot(root, entry["robot"], source, f"{where}.robot")
    data = Path(root) / entry["data"]
    if not data.is_file():
        from ..safeio import regular_file  # a FIFO, a device or a directory is named as such

        regular_file(data, source=source, field=f"{where}.data")
        raise InputError(f"no such file: {entry['data']}", source=source, field=f"{where}.data")
    _check_data(data, data_robot, memo)  # the data themselves (the message names the CSV, row and column)
    _check_lab_loads(entry, data_robot, source, where)
    force = entry.get("force_N", config["study"]["force_N"])
    moment = entry.get("moment_Nm", config["study"].get("moment_Nm"))
    field = f"{where}.force_N" + ("" if "force_N" in entry else " (not given: the study's force_N, its default)")
    mfield = f"{where}.moment_Nm" + ("" if "moment_Nm" in entry else " (not given: the study's moment_Nm, its default)")
    from ..measured.measurements import check_noise_levels

    check_noise_levels("sigma_m" in entry, "sigma_rad" in entry, source, f"{where}.")
    if entry.get("test_pose_deg") is not None:  # the data set's own test pose: its robot's joints and limits
        from ..planning.study import check_test_inputs

        check_test_inputs(data_robot, entry["test_pose_deg"], np.asarray(force, float), f"{where}.test_pose_deg",
                          field, source, None if moment is None else np.asarray(moment, float), mfield)
    elif data_robot.n_joints == robot.n_joints:  # the predicted gain at the study's test pose
        if len(force) != data_robot.task_dim:
            raise InputError(f"expected {data_robot.task_dim} force components for the {data_robot.kind} robot "
                             f"{entry['robot']}, got {len(force)}", source=source, field=field)
        dm = moment_dim(data_robot)
        if moment is not None and len(moment) != dm:
            raise InputError(f"expected {dm} moment component(s) for the {data_robot.kind} robot "
                             f"{entry['robot']}, got {len(moment)}", source=source, field=mfield)
        if not any(force) and not any(moment or []):
            raise InputError("expected a nonzero force at the test pose", source=source, field=field)
        check_load_bends(data_robot, study.test_pose, np.r_[force, moment or []], field, source)


def check_config(config: dict, root: str | Path = ".", source: str = DEFAULT,
                 memo_dir: str | Path | None = None) -> None:
    """Check a workflow config completely (module docstring); raise :class:`InputError` naming ``source`` and
    the field. memo_dir: a folder where the check keeps the fingerprints of the measured-data files it has read
    and found good (their bytes, the robot they were read for and the package's source,
    ``data-checked.json``; :mod:`stiffcal.memo`), so that a rerun does not read them again; None: every file
    is read every time."""
    from ..planning.maps import map_studies
    from ..planning.study import design_studies, study_from_config
    from ..validation import validate

    validate(config, "config", source)
    _check_load_ranges(config, source)
    study = study_from_config(config, root, source)
    robot = study.robot
    if robot.n_joints != 2 or study.problem("ot").min_poses != 1:
        raise InputError(f"expected a robot with 2 joints whose single pose identifies both compliances (Tables 2-3 "
                         f"and Figures 4-5 are over (q1, q2)), got {robot.n_joints} joints; put other robots in "
                         "'studies'", source=source, field="study.robot")
    if robot.joint_columns("q") != ["q1", "q2"]:
        raise InputError(f"expected the paper's joint names q1, q2 for the paper's study (its tables and figures "
                         f"compare with the paper's printed q1, q2), got joint_names {list(robot.joint_names)}; "
                         "put named robots in 'studies'", source=source, field="study.robot")
    design_studies(config, root, source)
    map_studies(config, root, source)
    names = set()
    memo = None
    if memo_dir is not None:
        from ..memo import JsonMemo, package_fingerprint

        memo = JsonMemo(Path(memo_dir) / "data-checked.json", package_fingerprint())
    for i, entry in enumerate(config.get("measured_data") or []):
        if entry["name"] in names:
            raise InputError(f"expected unique names, got {entry['name']!r} twice", source=source,
                             field=f"measured_data[{i}].name")
        names.add(entry["name"])
        _check_measured_entry(config, entry, f"measured_data[{i}]", study, root, source, memo)
