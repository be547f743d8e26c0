"""Rule discriminate: plan.json and the plan figure of one measured data set."""
from stiffcal.workflow import pipeline

pipeline.run(snakemake, pipeline.discriminate, snakemake.params.entry, str(snakemake.output.plan))
