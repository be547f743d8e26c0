"""Rule fig6: 1/chi over the test-pose plane (Figure 6)."""
from stiffcal import pipeline

pipeline.run(snakemake, pipeline.fig6, snakemake.input.map, snakemake.output.png)
