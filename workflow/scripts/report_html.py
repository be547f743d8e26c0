"""Rule report_html: render paper/build/report.html from the generated tables and figures."""
from pathlib import Path

from stiffcal import pipeline

i = snakemake.input
tables = {k: i[k] for k in ("table2", "table3", "comparison", "validation")}
figures = {k: i[k] for k in ("fig3", "fig4", "fig5")}
rules = {"table2": "table2", "table3": "table3", "comparison": "paper_comparison", "validation": "validation",
         "fig3": "fig3", "fig4": "fig4", "fig5": "chi_map + fig5"}
pipeline.run(snakemake, pipeline.report_html, snakemake.config, tables, figures, i.printed, rules,
             str(Path(i.template).parent), snakemake.output.html)
