# Measured data: what the stiffness model gets wrong (stiffcal discrepancy), one job per data set.


rule discrepancy:
    input:
        data=lambda wc: MEASURED[wc.dataset]["data"],
        robot=lambda wc: MEASURED[wc.dataset]["robot"],
    output:
        verdict="results/discrepancy/{dataset}/verdict.json",
        png="results/discrepancy/{dataset}/residuals.png",
        svg="results/discrepancy/{dataset}/residuals.svg",
    log:
        f"{LOGS}/discrepancy/{{dataset}}.log",
    benchmark:
        f"benchmarks/out/discrepancy/{{dataset}}.tsv",
    conda:
        ENV
    script:
        "../scripts/discrepancy.py"


# The next experiment that tells the verdict's rival causes apart (stiffcal discriminate), one job per data set.


rule discriminate:
    input:
        data=lambda wc: MEASURED[wc.dataset]["data"],
        robot=lambda wc: MEASURED[wc.dataset]["robot"],
    output:
        plan="results/discrepancy/{dataset}/plan.json",
        png="results/discrepancy/{dataset}/plan.png",
        svg="results/discrepancy/{dataset}/plan.svg",
    params:
        p=discriminate_params,
    log:
        f"{LOGS}/discriminate/{{dataset}}.log",
    benchmark:
        f"benchmarks/out/discriminate/{{dataset}}.tsv",
    conda:
        ENV
    script:
        "../scripts/discriminate.py"
