# The archive for reviewers (`make archive`): exactly what this config's workflow made (the outputs `all` asks
# for, the report, the logs of their jobs), the effective config and every file the config refers to, with
# provenance.json and SHA256SUMS; `stiffcal verify-archive FILE` checks it. Not part of `all`.
from stiffcal.workflow.archive import config_files as _config_files
from stiffcal.workflow.archive import run_status as _run_status

# named for its commit, with '-dirty' when the tree or an input (the config, a file it names) is not as committed
ARCHIVE = f"results/archive/stiffcal-{_run_status(config, '.', CONFIG_SOURCE, packages=False)['commit']}.tar.gz"


rule archive:
    input:
        unpack(report_inputs),
        html=rules.report_html.output.html,
        pdf=rules.report_pdf.output.pdf,
        made=all_outputs,
        inputs=lambda wc: [str(p) for p in _config_files(config, ".")],
    output:
        tgz=ARCHIVE,
    params:
        config=config,
        files=archive_files,
        config_source=CONFIG_SOURCE,
    log:
        f"{LOGS}/archive.log",
    conda:
        ENV
    script:
        "../scripts/archive.py"
