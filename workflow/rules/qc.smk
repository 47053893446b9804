# Batch QC report, one per batch of the sample sheet: per-ball ITF verdicts over several drops,
# batch mean and spread, control chart of the rebound height (PNG) and the recordings that failed.


rule qc:
    input:
        fits=batch_fits,
    output:
        html=report("results/batch/qc_{batch}.html", caption="../report/qc.rst", category="Batch",
                    labels={"batch": "{batch}", "figure": "QC report"}),
        figure=report("results/batch/qc_{batch}.png", caption="../report/qc_chart.rst", category="Batch",
                      labels={"batch": "{batch}", "figure": "control chart"}),
        balls="results/batch/qc_{batch}_balls.csv",
    params:
        ball_ids=batch_ball_ids,
        options=qc_args,
    log:
        "results/logs/qc/{batch}.log",
    conda:
        "../envs/dropfit.yaml"
    shell:
        "dropfit qc {input.fits} --ball-ids {params.ball_ids} --batch={wildcards.batch}"
        " --html={output.html} --figure={output.figure} --csv={output.balls}"
        " {params.options} > {log} 2>&1"
