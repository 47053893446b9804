# Recordings -> every per-recording file (trajectory.nc, impacts.csv, flights.csv, analysis.json, fit.json,
# report.html, report.png; for a video also track.csv and contact_sheet.png), a chunk of recordings per
# job: `dropfit batch` does each recording of its chunk as `dropfit run` does, in one Python process, so
# that a recording costs its work and not a process start-up. A recording that fails gets failure records
# and the chunk goes on. One rule per chunk (process_logs_<i>, process_videos_<i>; common.smk chunks).

for chunk, members in chunks.items():

    rule:
        name:
            chunk
        input:
            chunk_inputs(members),
        output:
            chunk_outputs(members),
        params:
            sheet=config["samples"],
            config=BATCH_CONFIG,
            rows=chunk_rows(members),
            sample_ids=" ".join(members),
        log:
            f"results/logs/process/{chunk}.log",
        resources:
            runtime=chunk_runtime(members),
        conda:
            "../envs/dropfit.yaml"
        shell:
            "dropfit batch --samples={params.sheet:q} --results=results --config={params.config:q}"
            " -- {params.sample_ids} > {log} 2>&1"
