"""Rule report_html: render paper/build/report.html from the generated tables and figures."""
from stiffcal.workflow import pipeline

pipeline.run(snakemake, pipeline.report_html_from_inputs, snakemake.params.config, dict(snakemake.input.items()),
             snakemake.output.html)
