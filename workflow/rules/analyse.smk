# Trajectory -> impacts, flights (apex heights in m, times in s) and a per-sample analysis summary.


rule analyse:
    input:
        trajectory="results/{sample}/trajectory.nc",
    output:
        impacts="results/{sample}/impacts.csv",
        flights="results/{sample}/flights.csv",
        summary="results/{sample}/analysis.json",
    params:
        options=analyse_args,
    log:
        "results/logs/analyse/{sample}.log",
    shell:
        "dropfit analyse {input.trajectory} --impacts {output.impacts}"
        " --flights {output.flights} --summary {output.summary}"
        " {params.options} --record-failure > {log} 2>&1"
