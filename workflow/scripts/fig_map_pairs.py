"""Rule fig_map_pairs: where a designed second pose pays (the two-pose map of the paper's arm)."""
from stiffcal import pipeline

pipeline.run(snakemake, pipeline.fig_map_pairs, snakemake.input.pairs, snakemake.output.png)
