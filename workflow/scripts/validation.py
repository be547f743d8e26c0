"""Rule validation: Monte Carlo checks of eqs. 11 and 16."""
from stiffcal.workflow import pipeline

i = snakemake.input
pipeline.run(snakemake, pipeline.validation, snakemake.params.study, i.robot, i.table2, snakemake.output.csv)
