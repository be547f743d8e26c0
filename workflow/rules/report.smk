# The report: HTML from the generated tables and figures, then the PDF printed from that HTML.
# report_html shows config values and the config's hash, so it depends on the whole config.


rule report_html:
    input:
        unpack(report_inputs),
    output:
        html="paper/build/report.html",
    params:
        config=config,
        code=code_version("report_html_from_inputs"),
    log:
        f"{LOGS}/report_html.log",
    conda:
        ENV
    script:
        "../scripts/report_html.py"


rule report_pdf:
    input:
        unpack(report_figures),
        html=rules.report_html.output.html,
    output:
        pdf="paper/build/report.pdf",
    params:
        code=code_version("report_pdf"),
    log:
        f"{LOGS}/report_pdf.log",
    conda:
        ENV
    script:
        "../scripts/report_pdf.py"


rule effective_config:
    output:
        yaml=EFFECTIVE_CONFIG,
    params:
        config=config,
    log:
        f"{LOGS}/effective_config.log",
    conda:
        ENV
    script:
        "../scripts/effective_config.py"
