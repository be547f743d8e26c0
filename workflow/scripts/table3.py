"""Rule table3: each criterion's plan judged at the test pose (Table 3)."""
from stiffcal import pipeline

pipeline.run(snakemake, pipeline.table3, snakemake.config, snakemake.input.table2, snakemake.output.csv)
