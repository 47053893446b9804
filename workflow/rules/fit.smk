# Impacts -> restitution model fit and, for tennis balls, the ITF rebound verdict.


rule fit:
    input:
        analysis="results/{sample}/analysis.json",
        impacts="results/{sample}/impacts.csv",
    output:
        fit="results/{sample}/fit.json",
    params:
        options=fit_args,
    log:
        "results/logs/fit/{sample}.log",
    shell:
        "dropfit fit --analysis {input.analysis} --impacts {input.impacts}"
        " --out {output.fit} {params.options} --record-failure > {log} 2>&1"
