"""Rule report_html: render paper/build/report.html from the generated tables and figures."""
from pathlib import Path

from stiffcal import pipeline

i = snakemake.input
tables = {k: i[k] for k in ("table2", "table3", "table4", "table5", "design", "certificate", "ot_versus_m",
                            "comparison", "validation")}
figures = {k: i[k] for k in ("fig3", "fig4", "fig5", "fig_design", "fig_ot_versus_m")}
if "map_statistics" in i.keys():
    tables["map_statistics"] = i.map_statistics
    figures.update({k: i[k] for k in ("fig6", "fig7", "fig8", "fig9", "fig10") if k in i.keys()})
rules = {"table2": "table2", "table3": "table3", "table4": "plans_table (m = 2)", "table5": "plans_table (m = 3)",
         "design": "approximate_design", "ot_versus_m": "ot_versus_m", "comparison": "paper_comparison",
         "validation": "validation", "fig3": "fig3", "fig4": "fig4", "fig5": "chi_map + fig5",
         "fig_design": "approximate_design + phi_map + fig_design", "fig_ot_versus_m": "ot_versus_m + fig_ot_versus_m",
         "map_statistics": "map_tile + map_merge + map_statistics", "fig6": "map_tile + map_merge + fig6",
         "fig_map": "map_tile + map_merge + fig_map_poses"}
verdicts = {k.split("__", 1)[1]: i[k] for k in i.keys() if k.startswith("verdict__")}
figures.update({k: i[k] for k in i.keys() if k.startswith("residuals__")})
rules["discrepancy"] = "discrepancy"
rules |= {"study_plans": "study_design + study_plan + study_plans", "fig_study_plan": "study_plans + fig_study_plan",
          "fig_study_versus_m": "study_plans + fig_study_versus_m", "study_design": "study_design"}
studies = {k.split("__", 1)[1]: {part: i[f"{part}__{k.split('__', 1)[1]}"] for part in
                                 ("studycert", "studyplans", "studyfigplan", "studyfigm")}
           for k in i.keys() if k.startswith("studyplans__")}
pipeline.run(snakemake, pipeline.report_html, snakemake.config, tables, figures, i.printed, rules,
             str(Path(i.template).parent), snakemake.output.html, verdicts, studies)
