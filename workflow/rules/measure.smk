# Height log or video -> trajectory in SI units (m up, s) in the sensor's frame, with the ball's properties;
# a video's tracked table (px, quality flag per frame) too, kept even when the clip is then refused.


rule measure:
    wildcard_constraints:
        sample=_alternatives(log_samples),
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


rule measure_video:
    wildcard_constraints:
        sample=_alternatives(video_samples),
    input:
        measure_input,
    output:
        trajectory="results/{sample}/trajectory.nc",
        track="results/{sample}/track.csv",
    params:
        recording=recording_path,
        options=measure_args,
    log:
        "results/logs/measure/{sample}.log",
    shell:
        "dropfit measure {params.recording:q} --out {output.trajectory} --track {output.track}"
        " --sample-id {wildcards.sample} {params.options} --record-failure > {log} 2>&1"
