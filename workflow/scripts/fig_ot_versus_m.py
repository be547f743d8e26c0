"""Rule fig_ot_versus_m: best O_t against the number of poses, beside the bound."""
from stiffcal import pipeline

pipeline.run(snakemake, pipeline.fig_ot_versus_m, snakemake.input.csv, snakemake.output.png)
