"""Rule map_figures: Figure 6 (1/chi), Figures 7-10 (optimal poses over the test-pose plane) and the map of the
best two-pose plans."""
from stiffcal.workflow import pipeline

maps = {k.removeprefix("fig"): v for k, v in snakemake.input.items() if k.startswith("fig")}
pairs = list(snakemake.input.pairs)
pngs = {k.removesuffix("_png"): v for k, v in snakemake.output.items() if k.endswith("_png")}
pipeline.run(snakemake, pipeline.map_figures, maps, pngs, pairs[0] if pairs else None)
