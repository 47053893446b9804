# Recordings -> every per-recording file (trajectory.nc, impacts.csv, flights.csv, analysis.json, fit.json,
# report.html, report.png; for a video also track.csv and contact_sheet.png), a chunk of recordings per
# job: `dropfit batch` does each recording of its chunk as `dropfit run` does, in one Python process, so
# that a recording costs its work and not a process start-up. A recording that fails gets failure records
# and the chunk goes on. One rule per chunk (process_logs_<i>, process_videos_<i>; common.smk chunks).
# A video row with a sound track is measured by its picture and its sound together, as `dropfit run`
# does it (dropfit.pipeline.measure_sound_and_picture): its fit.json and report hold sound_and_picture,
# and where the picture is refused its sound's e is the result (the tracked table and contact sheet
# still written); a row of kind audio measures the sound track alone.

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
