"""Rule plans_table: Table 4 (two poses) or Table 5 (three poses), plans (i)-(iv)."""
from stiffcal.workflow import pipeline

i = snakemake.input
pipeline.run(snakemake, pipeline.plans_table, snakemake.params.study, i.robot, snakemake.params.m, i.design, i.table2,
             snakemake.output.csv)
