"""Rule ot_versus_m: best O_t for m = 1..m_max beside the certified bound."""
from stiffcal import pipeline

pipeline.run(snakemake, pipeline.ot_versus_m, snakemake.config, snakemake.input.design, snakemake.output.csv)
