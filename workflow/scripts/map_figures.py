"""Rule map_figures: Figure 6 (1/chi) and Figures 7-10 (optimal poses over the test-pose plane)."""
from stiffcal import pipeline

maps = {k.removeprefix("fig"): v for k, v in snakemake.input.items()}
pngs = {k.removesuffix("_png"): v for k, v in snakemake.output.items() if k.endswith("_png")}
pipeline.run(snakemake, pipeline.map_figures, maps, pngs)
