# Single-experiment results: Table 2 (optimal pose per criterion), Table 3 (judged at the test pose),
# the comparison with the paper's printed numbers, the Monte Carlo checks and the chi map of Figure 5.


rule table2:
    input:
        robot=ROBOT,
    output:
        csv=f"{TABLES}/table2.csv",
    log:
        f"{LOGS}/table2.log",
    benchmark:
        "benchmarks/out/table2.tsv"
    conda:
        ENV
    script:
        "../scripts/table2.py"


rule table3:
    input:
        robot=ROBOT,
        table2=rules.table2.output.csv,
    output:
        csv=f"{TABLES}/table3.csv",
    log:
        f"{LOGS}/table3.log",
    benchmark:
        f"benchmarks/out/table3.tsv",
    conda:
        ENV
    script:
        "../scripts/table3.py"


rule paper_comparison:
    input:
        table2=f"{TABLES}/table2.csv",
        table3=f"{TABLES}/table3.csv",
        table4=f"{TABLES}/table4.csv",
        table5=f"{TABLES}/table5.csv",
        printed=PRINTED,
        statistics=lambda wc: [p for k, p in map_report_inputs(wc).items() if k == "map_statistics"],
    output:
        csv=f"{TABLES}/paper_comparison.csv",
    log:
        f"{LOGS}/paper_comparison.log",
    benchmark:
        f"benchmarks/out/paper_comparison.tsv",
    conda:
        ENV
    script:
        "../scripts/paper_comparison.py"


rule validation:
    input:
        table2=rules.table2.output.csv,
    output:
        csv=f"{TABLES}/validation.csv",
    log:
        f"{LOGS}/validation.log",
    benchmark:
        "benchmarks/out/validation.tsv"
    conda:
        ENV
    script:
        "../scripts/validation.py"


rule chi_map:
    input:
        robot=ROBOT,
    output:
        csv="results/maps/fig5_chi.csv",
    log:
        f"{LOGS}/chi_map.log",
    benchmark:
        f"benchmarks/out/chi_map.tsv",
    conda:
        ENV
    script:
        "../scripts/chi_map.py"


# Plans of several poses: the approximate design and its certificate, Tables 4-5, O_t against m.


rule approximate_design:
    input:
        robot=ROBOT,
    output:
        json="results/design/approximate_design.json",
        support=f"{TABLES}/approximate_design.csv",
        certificate=f"{TABLES}/certificate.csv",
    log:
        f"{LOGS}/approximate_design.log",
    benchmark:
        "benchmarks/out/approximate_design.tsv"
    conda:
        ENV
    script:
        "../scripts/approximate_design.py"


rule plans_table:
    input:
        design=rules.approximate_design.output.json,
        table2=rules.table2.output.csv,
    output:
        csv=f"{TABLES}/table{{number}}.csv",
    wildcard_constraints:
        number="4|5",
    params:
        m=lambda wc: {"4": 2, "5": 3}[wc.number],
    log:
        f"{LOGS}/table{{number}}.log",
    benchmark:
        "benchmarks/out/table{number}.tsv"
    conda:
        ENV
    script:
        "../scripts/plans_table.py"


rule ot_versus_m:
    input:
        design=rules.approximate_design.output.json,
    output:
        csv=f"{TABLES}/ot_versus_m.csv",
    log:
        f"{LOGS}/ot_versus_m.log",
    benchmark:
        "benchmarks/out/ot_versus_m.tsv"
    conda:
        ENV
    script:
        "../scripts/ot_versus_m.py"


rule phi_map:
    input:
        design=rules.approximate_design.output.json,
    output:
        csv="results/maps/design_phi.csv",
    log:
        f"{LOGS}/phi_map.log",
    benchmark:
        f"benchmarks/out/phi_map.tsv",
    conda:
        ENV
    script:
        "../scripts/phi_map.py"
