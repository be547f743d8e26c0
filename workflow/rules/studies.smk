# Design studies (config `studies`): any robot file, planar n-link or spatial. Per study: the optimal
# approximate design with its certificate and the candidate pool of its plans (pool.npy), one job for the best
# plan of every M of `m_values` (best_plans.csv: it reads the design and the pool once), and one job that
# collects the plans (versus_m.csv: O_t, chi, bound per M; plans.csv: the poses, one row each) and draws the
# plan in 3-D and O_t and chi against M. Adding a robot is adding its YAML file and an entry.


rule study_design:
    input:
        robot=lambda wc: STUDIES[wc.name]["robot"],
        urdf=study_files,
    output:
        json=f"{STUDY_DIR}/{{name}}/approximate_design.json",
        support=f"{STUDY_DIR}/{{name}}/approximate_design.csv",
        certificate=f"{STUDY_DIR}/{{name}}/certificate.csv",
        pool=f"{STUDY_DIR}/{{name}}/pool.npy",
    params:
        study=study_entry,
        code=code_version("approximate_design"),
    log:
        f"{LOGS}/studies/{{name}}/design.log",
    conda:
        ENV
    script:
        "../scripts/study_design.py"


rule study_plans:
    input:
        robot=lambda wc: STUDIES[wc.name]["robot"],
        urdf=study_files,
        design=rules.study_design.output.json,
        pool=rules.study_design.output.pool,
    output:
        csv=f"{STUDY_DIR}/{{name}}/best_plans.csv",
    params:
        study=study_entry,
        m_values=lambda wc: STUDIES[wc.name]["m_values"],
        seed=SEED,
        code=code_version("study_plans"),
    log:
        f"{LOGS}/studies/{{name}}/plans.log",
    conda:
        ENV
    script:
        "../scripts/study_plans.py"


rule study_summary:
    input:
        robot=lambda wc: STUDIES[wc.name]["robot"],
        urdf=study_files,
        plans=rules.study_plans.output.csv,
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
