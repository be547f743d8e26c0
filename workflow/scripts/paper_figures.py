"""Rule paper_figures: Figures 3-5, the approximate design and O_t against m (PNG and SVG each)."""
from stiffcal.workflow import pipeline

i, o = snakemake.input, snakemake.output
pngs = {k.removesuffix("_png"): v for k, v in o.items() if k.endswith("_png")}
pipeline.run(snakemake, pipeline.paper_figures, snakemake.params.study, i.robot, i.table2, i.chi, i.support, i.phi,
             i.ot_versus_m, pngs)
