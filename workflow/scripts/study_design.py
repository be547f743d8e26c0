"""Rule study_design: the optimal approximate design and certificate of one design study, and the candidate pool
of its plans."""
from stiffcal.workflow import pipeline

o = snakemake.output
pipeline.run(snakemake, pipeline.approximate_design, snakemake.params.study, snakemake.input.robot, o.json, o.support,
             o.certificate, None, snakemake.wildcards.name, o.pool)
