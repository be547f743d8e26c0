"""Rule map_merge: results/maps/<study>/map.npz and map.csv from its tiles."""
from stiffcal import pipeline

pipeline.run(snakemake, pipeline.map_merge, snakemake.config, snakemake.wildcards.study,
             list(snakemake.input.tiles), snakemake.output.npz, snakemake.output.csv)
