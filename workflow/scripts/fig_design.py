"""Rule fig_design: the optimal approximate design over the phi map."""
from stiffcal import pipeline

pipeline.run(snakemake, pipeline.fig_design, snakemake.input.support, snakemake.input.phi, snakemake.output.png)
