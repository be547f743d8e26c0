# Figures of the paper's study: plot rules only read generated tables, so restyling never reruns an
# optimisation. The five figures are drawn by one job (each takes a fraction of a second; one start-up).

PAPER_FIGURES = ("fig3", "fig4", "fig5", "fig_design", "fig_ot_versus_m")


rule paper_figures:
    input:
        robot=ROBOT,
        table2=rules.table2.output.csv,
        chi=rules.chi_map.output.csv,
        support=rules.approximate_design.output.support,
        phi=rules.approximate_design.output.phi,
        ot_versus_m=rules.ot_versus_m.output.csv,
    output:
        **{f"{name}_{ext}": f"{FIGURES}/{name}.{ext}" for name in PAPER_FIGURES for ext in ("png", "svg")},
    params:
        study=study_params("test_pose_deg", "force_N"),
        code=code_version("paper_figures"),
    log:
        f"{LOGS}/paper_figures.log",
    conda:
        ENV
    script:
        "../scripts/paper_figures.py"
