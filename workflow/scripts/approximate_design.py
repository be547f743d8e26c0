"""Rule approximate_design: the optimal approximate design for O_t and its certificate."""
from stiffcal import pipeline

o = snakemake.output
pipeline.run(snakemake, pipeline.approximate_design, snakemake.config, o.json, o.support, o.certificate)
