"""Rule paper_comparison: every printed number of Tables 2-5 beside ours, with a status."""
from stiffcal import pipeline

i = snakemake.input
pipeline.run(snakemake, pipeline.comparison, snakemake.params.study, i.robot, i.table2, i.table3, i.table4, i.table5,
             i.printed, snakemake.output.csv)
