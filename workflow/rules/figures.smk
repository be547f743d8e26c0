# Figures: plot rules only read generated tables, so restyling never reruns an optimisation.


rule fig3:
    input:
        table2=rules.table2.output.csv,
    output:
        png=f"{FIGURES}/fig3.png",
        svg=f"{FIGURES}/fig3.svg",
    log:
        f"{LOGS}/fig3.log",
    script:
        "../scripts/fig3.py"


rule fig4:
    input:
        table2=rules.table2.output.csv,
    output:
        png=f"{FIGURES}/fig4.png",
        svg=f"{FIGURES}/fig4.svg",
    log:
        f"{LOGS}/fig4.log",
    script:
        "../scripts/fig4.py"


rule fig5:
    input:
        table2=rules.table2.output.csv,
        chi=rules.chi_map.output.csv,
    output:
        png=f"{FIGURES}/fig5.png",
        svg=f"{FIGURES}/fig5.svg",
    log:
        f"{LOGS}/fig5.log",
    script:
        "../scripts/fig5.py"
