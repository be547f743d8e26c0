"""Rule study_plans: the plans of every m of one design study in one table."""
from stiffcal import pipeline

pipeline.run(snakemake, pipeline.study_plans, list(snakemake.input.csvs), snakemake.output.csv)
