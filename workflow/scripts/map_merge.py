"""Rule map_merge: results/maps/<study>/map.csv from its tiles."""
from stiffcal import pipeline

pipeline.run(snakemake, pipeline.map_merge, snakemake.params.map, list(snakemake.input.tiles), snakemake.output.csv)
