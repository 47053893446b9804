# The batch summary over all samples: one row per recording, failed ones with their reason.


rule summary:
    input:
        fits=all_fits,
    output:
        csv=report("results/batch/summary.csv", caption="../report/summary.rst", category="Batch"),
        html=report("results/batch/summary.html", caption="../report/summary.rst", category="Batch"),
    log:
        "results/logs/summary/batch.log",
    conda:
        "../envs/dropfit.yaml"
    shell:
        "dropfit summary {input.fits} --csv={output.csv} --html={output.html} > {log} 2>&1"
