"""Rule chi_map: chi over the measurement-pose plane (data of Figure 5)."""
from stiffcal.workflow import pipeline

pipeline.run(snakemake, pipeline.chi_map, snakemake.params.study, snakemake.input.robot, snakemake.output.csv)
