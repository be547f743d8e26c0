"""Rule discriminate: plan.json and the plan figure of one measured data set."""
from stiffcal import pipeline

pipeline.run(snakemake, pipeline.discriminate, snakemake.params.p, str(snakemake.output.plan))
