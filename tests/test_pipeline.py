"""The report rule's inputs sorted into tables, figures, verdicts and design studies."""

from stiffcal.pipeline import REPORT_RULES, report_inputs


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
