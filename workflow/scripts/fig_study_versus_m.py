"""Rule fig_study_versus_m: O_t and chi of a design study against the number of poses."""
from stiffcal import pipeline

pipeline.run(snakemake, pipeline.fig_study_versus_m, snakemake.config, snakemake.wildcards.name,
             snakemake.input.plans, snakemake.output.png)
