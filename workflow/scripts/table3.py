"""Rule table3: each criterion's plan judged at the test pose (Table 3)."""
from stiffcal.workflow import pipeline

i = snakemake.input
pipeline.run(snakemake, pipeline.table3, snakemake.params.study, i.robot, i.table2, snakemake.output.csv)
