"""Rule paper_comparison: every result number the paper prints (Tables 2-5, text) beside ours, with a status."""
from stiffcal.workflow import pipeline

i = snakemake.input
stats = list(i.figure6_stats)  # [] when the config has no map of the paper's arm (Figure 7)
pipeline.run(snakemake, pipeline.comparison, snakemake.params.study, i.robot, i.table2, i.table3, i.table4, i.table5,
             i.printed, snakemake.output.csv, stats[0] if stats else None)
