"""Rule discrepancy: verdict.json, the residual and held-out figures and calibrated.yaml of one measured data set."""
from stiffcal.workflow import pipeline

pipeline.run(snakemake, pipeline.discrepancy, snakemake.params.entry, str(snakemake.output.verdict))
