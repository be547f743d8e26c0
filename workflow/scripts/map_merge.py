"""Rule map_merge: results/maps/<study>/map.npz (for the other jobs) and map.csv (for users) from its tiles."""
from stiffcal.workflow import pipeline

pipeline.run(snakemake, pipeline.map_merge, snakemake.params.map, list(snakemake.input.tiles), snakemake.output.npz,
             snakemake.output.csv)
