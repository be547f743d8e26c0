# The report: HTML from the generated tables and figures, then the PDF printed from that HTML.
# report_html shows config values and the config's hash, so it depends on the whole config.


rule report_html:
    input:
        unpack(map_report_inputs),
        unpack(discrepancy_report_inputs),
        unpack(study_report_inputs),
        table2=rules.table2.output.csv,
        table3=rules.table3.output.csv,
        comparison=rules.paper_comparison.output.csv,
        validation=rules.validation.output.csv,
        table4=f"{TABLES}/table4.csv",
        table5=f"{TABLES}/table5.csv",
        design=rules.approximate_design.output.support,
        certificate=rules.approximate_design.output.certificate,
        ot_versus_m=rules.ot_versus_m.output.csv,
        fig3=f"{FIGURES}/fig3.svg",
        fig4=f"{FIGURES}/fig4.svg",
        fig5=f"{FIGURES}/fig5.svg",
        fig_design=f"{FIGURES}/fig_design.svg",
        fig_ot_versus_m=f"{FIGURES}/fig_ot_versus_m.svg",
        printed=PRINTED,
        template="paper/templates/report.html.j2",
        css="paper/templates/report.css",
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
