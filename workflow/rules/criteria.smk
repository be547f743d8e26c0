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
    script:
        "../scripts/table3.py"


rule paper_comparison:
    input:
        table2=rules.table2.output.csv,
        table3=rules.table3.output.csv,
        printed=PRINTED,
    output:
        csv=f"{TABLES}/paper_comparison.csv",
    log:
        f"{LOGS}/paper_comparison.log",
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
    script:
        "../scripts/validation.py"


rule chi_map:
    input:
        robot=ROBOT,
    output:
        csv="results/maps/fig5_chi.csv",
    log:
        f"{LOGS}/chi_map.log",
    script:
        "../scripts/chi_map.py"
