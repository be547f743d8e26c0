"""Rule map_tile: one tile of a map over test poses."""
from stiffcal import pipeline

pipeline.run(snakemake, pipeline.map_tile, snakemake.params.map, int(snakemake.wildcards.tile), snakemake.output.csv)
