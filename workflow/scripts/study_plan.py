"""Rule study_plan: the best plan of m poses of one design study, with its bound."""
from stiffcal import pipeline

i = snakemake.input
pipeline.run(snakemake, pipeline.study_plan, snakemake.params.study, i.robot, int(snakemake.wildcards.m),
             int(snakemake.params.seed), i.design, snakemake.output.csv)
