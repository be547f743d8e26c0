"""Rule table2: optimal single pose per criterion (Table 2)."""
from stiffcal.workflow import pipeline

pipeline.run(snakemake, pipeline.table2, snakemake.params.study, snakemake.input.robot, snakemake.output.csv)
