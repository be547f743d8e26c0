# stiffcal workflow: rebuilds the seed paper's tables and figures and renders the report.
#   snakemake --cores 2 --workflow-profile workflow/profiles/default     (what `make report` runs)
# Config: config/config.yaml (documented in workflow/schemas/config.schema.yaml and README.md).
from snakemake.utils import min_version, validate

min_version("9.0")


configfile: "config/config.yaml"


validate(config, "workflow/schemas/config.schema.yaml")


include: "workflow/rules/common.smk"
include: "workflow/rules/criteria.smk"
include: "workflow/rules/figures.smk"
include: "workflow/rules/maps.smk"
include: "workflow/rules/discrepancy.smk"
include: "workflow/rules/studies.smk"
include: "workflow/rules/report.smk"
include: "workflow/rules/archive.smk"


rule all:
    input:
        rules.report_html.output.html,
        rules.report_pdf.output.pdf,
    default_target: True
