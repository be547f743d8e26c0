"""Rule fig_map_poses: the optimal measurement pose over the test-pose plane (Figures 7-10)."""
from stiffcal import pipeline

pipeline.run(snakemake, pipeline.fig_map_poses, snakemake.input.map, int(snakemake.wildcards.mapfig),
             snakemake.output.png)
