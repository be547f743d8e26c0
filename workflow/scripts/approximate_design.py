"""Rule approximate_design: the optimal approximate design for O_t, its certificate and the phi map."""
from stiffcal.workflow import pipeline

o = snakemake.output
pipeline.run(snakemake, pipeline.approximate_design, snakemake.params.study, snakemake.input.robot, o.json, o.support,
             o.certificate, o.phi)
