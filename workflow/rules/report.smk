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


def report_figures(wildcards):
    """The SVG figures the HTML report embeds, and their PNG renditions, which the PDF prints instead (drawing
    an SVG is most of WeasyPrint's work; docs/workflow.md)."""
    svgs = sorted(v for v in report_inputs(wildcards).values() if v.endswith(".svg"))
    return {"svgs": svgs, "pngs": [v.removesuffix(".svg") + ".png" for v in svgs]}


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
