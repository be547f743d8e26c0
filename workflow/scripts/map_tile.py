"""Rule map_tile: one tile of a map over test poses (written as a binary tile file)."""
from stiffcal import pipeline

w = snakemake.wildcards
pipeline.run(snakemake, pipeline.map_tile, snakemake.config, w.study, int(w.tile), snakemake.output.npz)
