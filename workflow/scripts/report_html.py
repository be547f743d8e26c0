"""Rule report_html: render paper/build/report.html from the generated tables and figures."""
from pathlib import Path

from stiffcal import pipeline

i = snakemake.input
tables = {k: i[k] for k in ("table2", "table3", "table4", "table5", "design", "certificate", "ot_versus_m",
                            "comparison", "validation")}
figures = {k: i[k] for k in ("fig3", "fig4", "fig5", "fig_design", "fig_ot_versus_m")}
rules = {"table2": "table2", "table3": "table3", "table4": "plans_table (m = 2)", "table5": "plans_table (m = 3)",
         "design": "approximate_design", "ot_versus_m": "ot_versus_m", "comparison": "paper_comparison",
         "validation": "validation", "fig3": "fig3", "fig4": "fig4", "fig5": "chi_map + fig5",
         "fig_design": "approximate_design + phi_map + fig_design", "fig_ot_versus_m": "ot_versus_m + fig_ot_versus_m"}
pipeline.run(snakemake, pipeline.report_html, snakemake.config, tables, figures, i.printed, rules,
             str(Path(i.template).parent), snakemake.output.html)
