"""Rule study_design: the optimal approximate design and certificate of one design study."""
from stiffcal import pipeline

o = snakemake.output
pipeline.run(snakemake, pipeline.approximate_design, snakemake.config, o.json, o.support, o.certificate,
             snakemake.wildcards.name)
