"""Rule map_tile: one tile of a map over test poses (Figures 6-10), as a binary tile file."""
from stiffcal.workflow import pipeline

pipeline.run(snakemake, pipeline.map_tile, snakemake.params.map, int(snakemake.wildcards.tile), snakemake.output.npz)
