"""Rule map_tile: one tile of a map over test poses."""
from stiffcal import pipeline

w = snakemake.wildcards
pipeline.run(snakemake, pipeline.map_tile, snakemake.config, w.study, int(w.tile), snakemake.output.csv)
