# The batch summary over all samples: one row per recording (linked to its report), failed ones with their
# reason, the sample sheet's free columns carried, and e charted against each numeric one.


rule summary:
    input:
        fits=all_fits,
        reports=all_reports,
        samples=config["samples"],
    output:
        csv=report("results/batch/summary.csv", caption="../report/summary.rst", category="Batch"),
        html=report("results/batch/summary.html", caption="../report/summary.rst", category="Batch"),
        figure=report("results/batch/summary_extras.png", caption="../report/summary.rst", category="Batch"),
    log:
        "results/logs/summary/batch.log",
    conda:
        "../envs/dropfit.yaml"
    shell:
        "dropfit summary {input.fits} --samples={input.samples:q} --csv={output.csv} --html={output.html}"
        " --figure={output.figure} > {log} 2>&1"
