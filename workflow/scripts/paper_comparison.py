"""Rule paper_comparison: every result number the paper prints (Tables 2-5, text) beside ours, with a status."""
from stiffcal import pipeline

i = snakemake.input
maps = list(i.figure6_map)  # [] when the config has no map of the paper's arm (Figure 7)
pipeline.run(snakemake, pipeline.comparison, snakemake.params.study, i.robot, i.table2, i.table3, i.table4, i.table5,
             i.printed, snakemake.output.csv, maps[0] if maps else None)
