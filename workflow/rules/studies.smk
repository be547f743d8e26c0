# Design studies (config `studies`): any robot file, planar n-link or spatial. Per study: the optimal
# approximate design with its certificate, the best plan for every M of `m_values` (one job each), the
# plan drawn in 3-D and O_t and chi against M. Adding a robot is adding its YAML file and an entry.


rule study_design:
    input:
        robot=lambda wc: STUDIES[wc.name]["robot"],
    output:
        json=f"{STUDY_DIR}/{{name}}/approximate_design.json",
        support=f"{STUDY_DIR}/{{name}}/approximate_design.csv",
        certificate=f"{STUDY_DIR}/{{name}}/certificate.csv",
    log:
        f"{LOGS}/studies/{{name}}/design.log",
    benchmark:
        "benchmarks/out/studies/{name}/design.tsv"
    conda:
        ENV
    script:
        "../scripts/study_design.py"


rule study_plan:
    input:
        design=rules.study_design.output.json,
    output:
        csv=temp(f"{STUDY_DIR}/{{name}}/plans/m{{m}}.csv"),
    log:
        f"{LOGS}/studies/{{name}}/plan_m{{m}}.log",
    benchmark:
        "benchmarks/out/studies/{name}/plan_m{m}.tsv"
    conda:
        ENV
    script:
        "../scripts/study_plan.py"


rule study_plans:
    input:
        csvs=lambda wc: expand(f"{STUDY_DIR}/{wc.name}/plans/m{{m}}.csv", m=STUDIES[wc.name]["m_values"]),
    output:
        csv=f"{STUDY_DIR}/{{name}}/plans.csv",
    log:
        f"{LOGS}/studies/{{name}}/plans.log",
    benchmark:
        f"benchmarks/out/studies/{{name}}/plans.tsv",
    conda:
        ENV
    script:
        "../scripts/study_plans.py"


rule fig_study_plan:
    input:
        plans=rules.study_plans.output.csv,
    output:
        png=f"{FIGURES}/studies/{{name}}/plan.png",
        svg=f"{FIGURES}/studies/{{name}}/plan.svg",
    log:
        f"{LOGS}/studies/{{name}}/fig_plan.log",
    benchmark:
        f"benchmarks/out/studies/{{name}}/fig_plan.tsv",
    conda:
        ENV
    script:
        "../scripts/fig_study_plan.py"


rule fig_study_versus_m:
    input:
        plans=rules.study_plans.output.csv,
    output:
        png=f"{FIGURES}/studies/{{name}}/versus_m.png",
        svg=f"{FIGURES}/studies/{{name}}/versus_m.svg",
    log:
        f"{LOGS}/studies/{{name}}/fig_versus_m.log",
    benchmark:
        f"benchmarks/out/studies/{{name}}/fig_versus_m.tsv",
    conda:
        ENV
    script:
        "../scripts/fig_study_versus_m.py"
