"""Rule study_summary: one design study's plans (versus_m.csv, plans.csv) and its two figures."""
from stiffcal.workflow import pipeline

i, o = snakemake.input, snakemake.output
pipeline.run(snakemake, pipeline.study_summary, snakemake.params.study, i.robot, i.plans, o.versus_m, o.plans,
             o.plan_png, o.versus_m_png)
