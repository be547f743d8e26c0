"""Rule fig4: test pose and optimal measurement pose."""
from stiffcal import pipeline

pipeline.run(snakemake, pipeline.fig4, snakemake.config, snakemake.input.table2, snakemake.output.png)
