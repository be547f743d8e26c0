"""Rule discrepancy: verdict.json and the residual figure of one measured data set."""
from stiffcal import pipeline

pipeline.run(snakemake, pipeline.discrepancy, snakemake.params.entry, str(snakemake.output.verdict))
