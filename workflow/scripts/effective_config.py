"""Rule effective_config: results/config.effective.yaml, the config as the run saw it."""
from stiffcal.workflow import pipeline

pipeline.run(snakemake, pipeline.effective_config, snakemake.params.config, snakemake.output.yaml)
