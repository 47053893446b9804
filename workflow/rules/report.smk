# Per-sample HTML report with figure (for a video with the contact sheet of what was tracked, which the
# overlay job draws), and the batch summary over all samples.


rule overlay:
    wildcard_constraints:
        sample=_alternatives(video_samples),
    input:
        video=measure_input,
        track="results/{sample}/track.csv",
        trajectory="results/{sample}/trajectory.nc",
        flights="results/{sample}/flights.csv",
        impacts="results/{sample}/impacts.csv",
        analysis="results/{sample}/analysis.json",
    output:
        sheet=report(
            "results/{sample}/contact_sheet.png",
            category="What was tracked",
            labels={"sample": "{sample}", "figure": "contact sheet"},
        ),
    params:
        recording=recording_path,
        results=output_directory,
    log:
        "results/logs/overlay/{sample}.log",
    shell:
        "dropfit overlay {params.recording:q} --results {params.results} --out {output.sheet}"
        " --record-failure > {log} 2>&1"


rule report:
    input:
        trajectory="results/{sample}/trajectory.nc",
        flights="results/{sample}/flights.csv",
        impacts="results/{sample}/impacts.csv",
        analysis="results/{sample}/analysis.json",
        fit="results/{sample}/fit.json",
        contact_sheet=contact_sheet,
    output:
        html=report(
            "results/{sample}/report.html",
            category="Recordings",
            labels={"sample": "{sample}", "figure": "report"},
        ),
        figure=report(
            "results/{sample}/report.png",
            category="Recordings",
            labels={"sample": "{sample}", "figure": "figure"},
        ),
    params:
        contact_sheet=contact_sheet_option,
    log:
        "results/logs/report/{sample}.log",
    shell:
        "dropfit report --trajectory {input.trajectory} --flights {input.flights}"
        " --impacts {input.impacts} --analysis {input.analysis} --fit {input.fit} {params.contact_sheet}"
        " --html {output.html} --figure {output.figure} --record-failure > {log} 2>&1"


rule summary:
    input:
        fits=all_fits,
    output:
        csv="results/batch/summary.csv",
        html="results/batch/summary.html",
    log:
        "results/logs/summary/batch.log",
    shell:
        "dropfit summary {input.fits} --csv {output.csv} --html {output.html} > {log} 2>&1"
