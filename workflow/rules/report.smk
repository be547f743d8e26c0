# The report: HTML from the generated tables and figures, then the PDF printed from that HTML.


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
        fig3=rules.fig3.output.png,
        fig4=rules.fig4.output.png,
        fig5=rules.fig5.output.png,
        fig_design=rules.fig_design.output.png,
        fig_ot_versus_m=rules.fig_ot_versus_m.output.png,
        printed=PRINTED,
        template="paper/templates/report.html.j2",
        css="paper/templates/report.css",
    output:
        html="paper/build/report.html",
    log:
        f"{LOGS}/report_html.log",
    benchmark:
        f"benchmarks/out/report_html.tsv",
    conda:
        ENV
    script:
        "../scripts/report_html.py"


rule report_pdf:
    input:
        html=rules.report_html.output.html,
    output:
        pdf="paper/build/report.pdf",
    log:
        f"{LOGS}/report_pdf.log",
    benchmark:
        "benchmarks/out/report_pdf.tsv"
    conda:
        ENV
    script:
        "../scripts/report_pdf.py"
