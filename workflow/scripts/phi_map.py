"""Rule phi_map: the equivalence-theorem map phi(x, xi*) / Phi(xi*) over the measurement-pose plane."""
from stiffcal import pipeline

pipeline.run(snakemake, pipeline.phi_map, snakemake.config, snakemake.input.design, snakemake.output.csv)
