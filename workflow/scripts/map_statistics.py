"""Rule map_statistics: the statistics the paper quotes for Figure 6, ours beside theirs."""
from pathlib import Path

from stiffcal.workflow import pipeline

maps = {Path(p).parent.name: p for p in snakemake.input.maps}
grid = list(snakemake.input.grid)  # [] when the config has no map of the paper's arm (Figure 7)
pipeline.run(snakemake, pipeline.map_statistics, snakemake.params.maps, maps, snakemake.input.printed,
             snakemake.output.csv, grid[0] if grid else None)
