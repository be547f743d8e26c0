"""Rule fig5: chi map over measurement poses."""
from stiffcal import pipeline

pipeline.run(snakemake, pipeline.fig5, snakemake.input.table2, snakemake.input.chi, snakemake.output.png)
