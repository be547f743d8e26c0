"""Rule fig3: identification accuracy per criterion."""
from stiffcal import pipeline

pipeline.run(snakemake, pipeline.fig3, snakemake.input.table2, snakemake.output.png)
