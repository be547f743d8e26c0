"""Rule map_statistics: the statistics the paper quotes for Figure 6, ours beside theirs."""
from pathlib import Path

from stiffcal import pipeline

maps = {Path(p).parent.name: p for p in snakemake.input.maps}
pipeline.run(snakemake, pipeline.map_statistics, snakemake.params.maps, maps, snakemake.input.printed,
             snakemake.output.csv)
