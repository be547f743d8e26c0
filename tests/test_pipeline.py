"""The report rule's inputs sorted into tables, figures, verdicts and design studies."""

import pytest

from stiffcal.workflow.pipeline import REPORT_RULES, report_inputs


def test_report_inputs_are_sorted_by_their_names():
    named = {"table2": "t2.csv", "map_statistics": "ms.csv", "fig3": "f3.png", "fig7": "f7.png",
             "verdict__syn": "v.json", "residuals__syn": "r.png", "printed": "p.yaml", "template": "r.j2",
             "studycert__kuka": "c.csv", "studyplans__kuka": "p.csv", "studym__kuka": "m.csv",
             "studyfigplan__kuka": "fp.png", "studyfigm__kuka": "fm.png"}
    tables, figures, verdicts, studies = report_inputs(named)
    assert tables == {"table2": "t2.csv", "map_statistics": "ms.csv"}
    assert figures == {"fig3": "f3.png", "fig7": "f7.png", "residuals__syn": "r.png"}
    assert verdicts == {"syn": "v.json"}
    assert studies == {"kuka": {"studycert": "c.csv", "studyplans": "p.csv", "studym": "m.csv",
                                "studyfigplan": "fp.png", "studyfigm": "fm.png"}}
    assert {"study_plans", "fig_study_plan", "discrepancy", "table4"} <= set(REPORT_RULES)


def test_numeric_tables_are_written_byte_for_byte_as_pandas_writes_them(tmp_path):
    """tables.write_csv formats float64/int64 tables itself (the maps: 10^5 rows): the bytes of
    DataFrame.to_csv with the same float format, NaN as an empty field, inf, -0, extremes and integers."""
    import numpy as np
    import pandas as pd

    from stiffcal.csvtext import write_numeric_csv
    from stiffcal.paper.tables import FLOAT_FORMAT, _numeric_csv, write_csv

    rng = np.random.default_rng(7)
    x = rng.normal(size=500) * 10.0 ** rng.integers(-300, 300, 500)
    x[::37] = np.nan
    x[:8] = [0.0, -0.0, np.inf, -np.inf, 5e-324, 1.7976931348623157e308, 0.1, 2.0 / 3.0]
    df = pd.DataFrame({"a": x, "n": rng.integers(-10**12, 10**12, 500), "b": np.round(rng.normal(size=500) * 1000, 3)})
    expected = df.to_csv(index=False, float_format=FLOAT_FORMAT, lineterminator="\n")
    assert _numeric_csv(df) == expected
    write_csv(df, tmp_path / "t.csv")
    assert (tmp_path / "t.csv").read_text() == expected
    assert _numeric_csv(df.iloc[:0]) == df.iloc[:0].to_csv(index=False, lineterminator="\n")
    # anything else is left to pandas: text, booleans, names that need quoting
    for other in (df.assign(s="x"), df.assign(ok=True), df.rename(columns={"a": "a,b"})):
        assert _numeric_csv(other) is None
    with pytest.raises(ValueError, match="float64 or int64"):  # the map jobs' writer, without pandas
        write_numeric_csv({"s": np.array(["x"])}, tmp_path / "s.csv")
    assert not (tmp_path / "s.csv").exists()


def test_code_versions_hash_each_definition_as_the_standard_library_cuts_it():
    import ast

    from stiffcal.workflow.codeversion import PIPELINE, _pipeline_definitions, _segment, _source

    text = _source(PIPELINE)[0]
    defs = _pipeline_definitions()
    assert len(defs) >= 30
    assert all(_segment(name) == ast.get_source_segment(text, node) for name, node in defs.items())


def test_a_map_of_one_tile_is_computed_by_its_merge_job_as_by_a_tile_job(tmp_path):
    """map_merge without tile files (a map of one tile) writes the same map.npz and map.csv as the tile job and
    the merge of its tile file."""
    from stiffcal.workflow import pipeline
    from stiffcal.planning.maps import MapStudy

    p = {"name": "b0.5", "link_ratio": 0.5, "figure": 9, "step_deg": 10.0, "force_deg": -90.0, "tile_cells": 100000}
    assert MapStudy(**p).n_tiles == 1
    pipeline.map_tile(p, 0, str(tmp_path / "tile.npz"))
    pipeline.map_merge(p, [str(tmp_path / "tile.npz")], str(tmp_path / "a.npz"), str(tmp_path / "a.csv"))
    pipeline.map_merge(p, [], str(tmp_path / "b.npz"), str(tmp_path / "b.csv"))
    for ext in ("npz", "csv"):
        assert (tmp_path / f"a.{ext}").read_bytes() == (tmp_path / f"b.{ext}").read_bytes()


def test_the_candidate_pool_handed_over_is_the_one_the_plans_build(root, tmp_path):
    """study_design writes the pool that optimise_plan would build (exact floats); a damaged file is refused."""
    import numpy as np
    import pytest

    from stiffcal.workflow import pipeline
    from stiffcal.planning.certificate import candidate_pool, default_pool_step
    from stiffcal.errors import InputError

    study = pipeline._study({"test_pose_deg": [20, -60, 110, 30, 45, -20], "force_N": [500, -300, -800],
                             "sigma_m": 1e-5}, str(root / "config/robots/kuka_kr210_r2700.yaml"))
    pipeline._save_pool(str(tmp_path / "pool.npy"), study)
    pool = pipeline._pool(str(tmp_path / "pool.npy"), 6)
    built = candidate_pool(study.robot, default_pool_step(6), study.problem("ot", 6))
    assert pool.dtype == np.float64 and np.array_equal(pool, built)
    (tmp_path / "bad.npy").write_bytes((tmp_path / "pool.npy").read_bytes()[:1000])
    with pytest.raises(InputError, match="bad.npy"):
        pipeline._pool(str(tmp_path / "bad.npy"), 6)
    with pytest.raises(InputError, match=r"\(N, 3\)"):
        pipeline._pool(str(tmp_path / "pool.npy"), 3)
