"""Rule archive: results/archive/stiffcal-<commit>.tar.gz with provenance.json and SHA256SUMS."""
from stiffcal.workflow import pipeline

pipeline.run(snakemake, pipeline.archive, snakemake.params.config, snakemake.output.tgz, snakemake.params.files,
             snakemake.params.config_source)
