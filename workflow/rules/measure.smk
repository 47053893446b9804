# Height log -> trajectory in SI units (m, s) on the floor frame, with the ball's properties.


rule measure:
    input:
        recording=measure_input,
    output:
        trajectory="results/{sample}/trajectory.nc",
    params:
        options=measure_args,
    log:
        "results/logs/measure/{sample}.log",
    shell:
        "dropfit measure {input.recording} --out {output.trajectory}"
        " --sample-id {wildcards.sample} {params.options} --record-failure > {log} 2>&1"
