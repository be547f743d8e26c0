"""What the Snakemake workflow runs: one function per step (:mod:`stiffcal.workflow.pipeline`), the config, the
studies, the archive and the code versions that decide what reruns."""
