"""Rule map_pairs: the best plan of two poses over the test poses of a map study (case iv of Table 4)."""
from stiffcal.workflow import pipeline

pipeline.run(snakemake, pipeline.map_pairs, snakemake.params.map, snakemake.output.npz, snakemake.output.csv)
