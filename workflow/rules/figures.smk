# Figures: plot rules only read generated tables, so restyling never reruns an optimisation.


rule fig3:
    input:
        table2=rules.table2.output.csv,
    output:
        png=f"{FIGURES}/fig3.png",
        svg=f"{FIGURES}/fig3.svg",
    log:
        f"{LOGS}/fig3.log",
    benchmark:
        f"benchmarks/out/fig3.tsv",
    conda:
        ENV
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
    benchmark:
        f"benchmarks/out/fig4.tsv",
    conda:
        ENV
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
    benchmark:
        f"benchmarks/out/fig5.tsv",
    conda:
        ENV
    script:
        "../scripts/fig5.py"


rule fig_design:
    input:
        support=rules.approximate_design.output.support,
        phi=rules.phi_map.output.csv,
    output:
        png=f"{FIGURES}/fig_design.png",
        svg=f"{FIGURES}/fig_design.svg",
    log:
        f"{LOGS}/fig_design.log",
    benchmark:
        f"benchmarks/out/fig_design.tsv",
    conda:
        ENV
    script:
        "../scripts/fig_design.py"


rule fig_ot_versus_m:
    input:
        csv=rules.ot_versus_m.output.csv,
    output:
        png=f"{FIGURES}/fig_ot_versus_m.png",
        svg=f"{FIGURES}/fig_ot_versus_m.svg",
    log:
        f"{LOGS}/fig_ot_versus_m.log",
    benchmark:
        f"benchmarks/out/fig_ot_versus_m.tsv",
    conda:
        ENV
    script:
        "../scripts/fig_ot_versus_m.py"
