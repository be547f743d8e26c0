"""Rule report_pdf: print the HTML report to PDF with WeasyPrint (its SVG figures from their PNG renditions)."""
from stiffcal.workflow import pipeline

pipeline.run(snakemake, pipeline.report_pdf, snakemake.input.html, snakemake.output.pdf,
             list(snakemake.input.svgs))
