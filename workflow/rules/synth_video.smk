# Synthetic drop-test videos with per-frame ground truth, rendered from the flight and contact models
# (large files: written under results/, never committed).


rule synth_video:
    output:
        video=f"{VIDEO_DIR}/{{clip}}.avi",
        frames=f"{VIDEO_DIR}/{{clip}}.frames.csv",
        truth=f"{VIDEO_DIR}/{{clip}}.truth.json",
    params:
        out_dir=output_directory,
    log:
        "results/logs/synth_video/{clip}.log",
    conda:
        "../envs/dropfit.yaml"
    shell:
        "dropfit synth-video --name={wildcards.clip} --out-dir={params.out_dir} > {log} 2>&1"
