"""Rule ot_versus_m: best O_t for m = 1..m_max beside the certified bound."""
from stiffcal.workflow import pipeline

i = snakemake.input
pipeline.run(snakemake, pipeline.ot_versus_m, snakemake.params.study, i.robot, i.design, snakemake.output.csv)
