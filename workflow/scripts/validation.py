"""Rule validation: Monte Carlo checks of eqs. 11 and 16."""
from stiffcal import pipeline

pipeline.run(snakemake, pipeline.validation, snakemake.config, snakemake.input.table2, snakemake.output.csv)
