"""Rule study_plans: the best plan of every M of one design study, with its bound, one row each."""
from stiffcal.workflow import pipeline

i, p = snakemake.input, snakemake.params
pipeline.run(snakemake, pipeline.study_plans, p.study, i.robot, list(p.m_values), int(p.seed), i.design, i.pool,
             snakemake.output.csv)
