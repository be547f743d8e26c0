# Measured data: what the stiffness model gets wrong (stiffcal discrepancy), one job per data set.


rule discrepancy:
    input:
        data=lambda wc: MEASURED[wc.dataset]["data"],
        robot=lambda wc: MEASURED[wc.dataset]["robot"],
        urdf=lambda wc: robot_inputs(MEASURED[wc.dataset]["robot"]),
    output:
        verdict="results/discrepancy/{dataset}/verdict.json",
        png="results/discrepancy/{dataset}/residuals.png",
        svg="results/discrepancy/{dataset}/residuals.svg",
        heldout_png="results/discrepancy/{dataset}/heldout.png",
        heldout_svg="results/discrepancy/{dataset}/heldout.svg",
        machining_png="results/discrepancy/{dataset}/machining.png",
        machining_svg="results/discrepancy/{dataset}/machining.svg",
        calibrated="results/discrepancy/{dataset}/calibrated.yaml",
    params:
        # the entry without its next experiment's settings, which only rule discriminate reads
        entry=lambda wc: {**{k: v for k, v in MEASURED[wc.dataset].items() if k != "discriminate"},
                          "study_test_pose_deg": STUDY["test_pose_deg"]},
        code=code_version("discrepancy"),
    log:
        f"{LOGS}/discrepancy/{{dataset}}.log",
    conda:
        ENV
    script:
        "../scripts/discrepancy.py"


# The next experiment that tells the verdict's rival causes apart (stiffcal discriminate), one job per data set.


rule discriminate:
    input:
        data=lambda wc: MEASURED[wc.dataset]["data"],
        robot=lambda wc: MEASURED[wc.dataset]["robot"],
        urdf=lambda wc: robot_inputs(MEASURED[wc.dataset]["robot"]),
    output:
        plan="results/discrepancy/{dataset}/plan.json",
        png="results/discrepancy/{dataset}/plan.png",
        svg="results/discrepancy/{dataset}/plan.svg",
    params:
        entry=lambda wc: {**MEASURED[wc.dataset], "study_test_pose_deg": STUDY["test_pose_deg"]},
        code=code_version("discriminate"),
    log:
        f"{LOGS}/discriminate/{{dataset}}.log",
    conda:
        ENV
    script:
        "../scripts/discriminate.py"
