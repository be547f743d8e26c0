# Single-experiment results: Table 2 (optimal pose per criterion), Table 3 (judged at the test pose),
# the comparison with the paper's printed numbers, the Monte Carlo checks and the chi map of Figure 5.
# Every rule's `params:` hold exactly the config values it uses and the version of the code it runs.


rule table2:
    input:
        robot=ROBOT,
    output:
        csv=f"{TABLES}/table2.csv",
    params:
        study=study_params(*POSE_FORCE, "criteria", "search_step_deg"),
        code=code_version("table2"),
    log:
        f"{LOGS}/table2.log",
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
    params:
        study=study_params(*POSE_FORCE),
        code=code_version("table3"),
    log:
        f"{LOGS}/table3.log",
    conda:
        ENV
    script:
        "../scripts/table3.py"


rule paper_comparison:
    input:
        robot=ROBOT,
        table2=f"{TABLES}/table2.csv",
        table3=f"{TABLES}/table3.csv",
        table4=f"{TABLES}/table4.csv",
        table5=f"{TABLES}/table5.csv",
        printed=PRINTED,
        figure6_stats=[f"{MAPS}/{MAP_FIGURES[7]}/grid_statistics.npz"] if 7 in MAP_FIGURES else [],
    output:
        csv=f"{TABLES}/paper_comparison.csv",
    params:
        study={**study_params(*POSE_FORCE), "seed": SEED,
               "figure6": {**map_params(MAP_FIGURES[7]), "statistics_steps_deg": MAP_SETTINGS["statistics_steps_deg"]}
               if 7 in MAP_FIGURES else None},
        code=code_version("comparison"),
    log:
        f"{LOGS}/paper_comparison.log",
    conda:
        ENV
    script:
        "../scripts/paper_comparison.py"


rule validation:
    input:
        robot=ROBOT,
        table2=rules.table2.output.csv,
    output:
        csv=f"{TABLES}/validation.csv",
    params:
        study={**study_params(*POSE_FORCE), "samples": config["monte_carlo"]["samples"], "seed": SEED},
        code=code_version("validation"),
    log:
        f"{LOGS}/validation.log",
    conda:
        ENV
    script:
        "../scripts/validation.py"


rule chi_map:
    input:
        robot=ROBOT,
    output:
        csv="results/maps/fig5_chi.csv",
    params:
        study=study_params(*POSE_FORCE, "fig5_step_deg"),
        code=code_version("chi_map"),
    log:
        f"{LOGS}/chi_map.log",
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
        phi="results/maps/design_phi.csv",
    params:
        study={**study_params(*POSE_FORCE), "pool_step_deg": PLANS["pool_step_deg"]},
        code=code_version("approximate_design"),
    log:
        f"{LOGS}/approximate_design.log",
    conda:
        ENV
    script:
        "../scripts/approximate_design.py"


rule plans_table:
    input:
        robot=ROBOT,
        design=rules.approximate_design.output.json,
        table2=rules.table2.output.csv,
    output:
        csv=f"{TABLES}/table{{number}}.csv",
    wildcard_constraints:
        number="4|5",
    params:
        m=lambda wc: {"4": 2, "5": 3}[wc.number],
        study={**study_params(*POSE_FORCE), "seed": SEED},
        code=code_version("plans_table"),
    log:
        f"{LOGS}/table{{number}}.log",
    conda:
        ENV
    script:
        "../scripts/plans_table.py"


rule ot_versus_m:
    input:
        robot=ROBOT,
        design=rules.approximate_design.output.json,
    output:
        csv=f"{TABLES}/ot_versus_m.csv",
    params:
        study={**study_params(*POSE_FORCE, "search_step_deg"), "m_max": PLANS["m_max"], "seed": SEED},
        code=code_version("ot_versus_m"),
    log:
        f"{LOGS}/ot_versus_m.log",
    conda:
        ENV
    script:
        "../scripts/ot_versus_m.py"
