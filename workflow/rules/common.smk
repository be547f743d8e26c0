# Shared names for the rule files. Logic lives in src/stiffcal; this file only names paths.

TABLES = "results/tables"
FIGURES = "figures"
LOGS = "logs"
PRINTED = config["paper_values"]
ROBOT = config["study"]["robot"]
