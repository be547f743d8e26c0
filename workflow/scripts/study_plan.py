"""Rule study_plan: the best plan of m poses of one design study, with its bound."""
from stiffcal import pipeline

w = snakemake.wildcards
pipeline.run(snakemake, pipeline.study_plan, snakemake.config, w.name, int(w.m), snakemake.input.design,
             snakemake.output.csv)
