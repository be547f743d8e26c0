"""Rule fig_study_plan: a design study's plan drawn in 3-D."""
from stiffcal import pipeline

pipeline.run(snakemake, pipeline.fig_study_plan, snakemake.config, snakemake.wildcards.name, snakemake.input.plans,
             snakemake.output.png)
