# Height log -> trajectory in SI units (m up, s) in the sensor's frame, with the ball's properties.


rule measure:
    input:
        measure_input,
    output:
        trajectory="results/{sample}/trajectory.nc",
    params:
        recording=recording_path,
        options=measure_args,
    log:
        "results/logs/measure/{sample}.log",
    shell:
        "dropfit measure {params.recording:q} --out {output.trajectory}"
        " --sample-id {wildcards.sample} {params.options} --record-failure > {log} 2>&1"
