# Design studies (config `studies`): any robot file, planar n-link or spatial. Per study: the optimal
# approximate design with its certificate, the best plan for every M of `m_values` (one job each), and one
# job that collects the plans (versus_m.csv: O_t, chi, bound per M; plans.csv: the poses, one row each) and draws the plan in 3-D and O_t and chi
# against M. Adding a robot is adding its YAML file and an entry.


rule study_design:
    input:
        robot=lambda wc: STUDIES[wc.name]["robot"],
        urdf=lambda wc: robot_inputs(STUDIES[wc.name]["robot"]),
    output:
        json=f"{STUDY_DIR}/{{name}}/approximate_design.json",
        support=f"{STUDY_DIR}/{{name}}/approximate_design.csv",
        certificate=f"{STUDY_DIR}/{{name}}/certificate.csv",
    params:
        study=study_entry,
        code=code_version("approximate_design"),
    log:
        f"{LOGS}/studies/{{name}}/design.log",
    conda:
        ENV
    script:
        "../scripts/study_design.py"


rule study_plan:
    input:
        robot=lambda wc: STUDIES[wc.name]["robot"],
        urdf=lambda wc: robot_inputs(STUDIES[wc.name]["robot"]),
        design=rules.study_design.output.json,
    output:
        csv=f"{STUDY_DIR}/{{name}}/plans/m{{m}}.csv",
    params:
        study=study_entry,
        seed=SEED,
        code=code_version("study_plan"),
    log:
        f"{LOGS}/studies/{{name}}/plan_m{{m}}.log",
    conda:
        ENV
    script:
        "../scripts/study_plan.py"


rule study_summary:
    input:
        robot=lambda wc: STUDIES[wc.name]["robot"],
        urdf=lambda wc: robot_inputs(STUDIES[wc.name]["robot"]),
        csvs=lambda wc: expand(f"{STUDY_DIR}/{wc.name}/plans/m{{m}}.csv", m=STUDIES[wc.name]["m_values"]),
    output:
        versus_m=f"{STUDY_DIR}/{{name}}/versus_m.csv",
        plans=f"{STUDY_DIR}/{{name}}/plans.csv",
        plan_png=f"{FIGURES}/studies/{{name}}/plan.png",
        plan_svg=f"{FIGURES}/studies/{{name}}/plan.svg",
        versus_m_png=f"{FIGURES}/studies/{{name}}/versus_m.png",
        versus_m_svg=f"{FIGURES}/studies/{{name}}/versus_m.svg",
    params:
        study=lambda wc: {**study_entry(wc), "draw_m": STUDIES[wc.name]["draw_m"]},
        code=code_version("study_summary"),
    log:
        f"{LOGS}/studies/{{name}}/summary.log",
    conda:
        ENV
    script:
        "../scripts/study_summary.py"
