# stiffcal workflow: rebuilds the seed paper's tables and figures and renders the report.
#   snakemake --cores 2 --workflow-profile workflow/profiles/default     (what `make report` runs)
# Config: config/config.yaml, or instead one complete `--configfile FILE` (never merged with it); `--config
# KEY=VALUE` overrides either. Keys: docs/contracts.md; what reruns after an edit: docs/workflow.md.
# Everything in the config is checked here, before any job runs (stiffcal.workflow.config).
import os as _os
import sys as _sys

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):  # every job: one BLAS thread (small
    _os.environ.setdefault(_var, "1")  # matrices; jobs run side by side instead); set one to override

from snakemake.utils import min_version

from stiffcal.workflow.config import workflow_config as _workflow_config
from stiffcal.memo import WORKFLOW_MEMO_DIR as _MEMO_DIR
from stiffcal.errors import InputError as _InputError

min_version("9.0")

try:
    CONFIG_SOURCE, _config = _workflow_config(workflow.config_settings.configfiles,
                                              dict(workflow.config_settings.config), memo_dir=_MEMO_DIR)
except _InputError as _err:
    _sys.exit(f"stiffcal: error: {_err}")
config.clear()
config.update(_config)


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
        all_outputs,
    default_target: True
