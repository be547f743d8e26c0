"""Rule map_grid_statistics: the statistics of the map of Figure 7 on every grid of statistics_steps_deg."""
from stiffcal.workflow import pipeline

pipeline.run(snakemake, pipeline.map_grid_statistics, snakemake.params.map, snakemake.input.map,
             snakemake.output.npz)
