# The archive for reviewers (`make archive`): config, data, results, figures, logs and the report with
# provenance.json and SHA256SUMS; `stiffcal verify-archive FILE` checks it. Not part of `all`.
import datetime as _dt

from stiffcal.report import git_commit as _git_commit

RUN_STARTED = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
ARCHIVE = f"results/archive/stiffcal-{_git_commit()}.tar.gz"


rule archive:
    input:
        unpack(report_inputs),
        html=rules.report_html.output.html,
        pdf=rules.report_pdf.output.pdf,
    output:
        tgz=ARCHIVE,
    params:
        started=RUN_STARTED,
        config=config,
    log:
        f"{LOGS}/archive.log",
    conda:
        ENV
    script:
        "../scripts/archive.py"
