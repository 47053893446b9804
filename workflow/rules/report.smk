# Per-sample HTML report with figure, and the batch summary over all samples.


rule report:
    input:
        trajectory="results/{sample}/trajectory.nc",
        flights="results/{sample}/flights.csv",
        impacts="results/{sample}/impacts.csv",
        analysis="results/{sample}/analysis.json",
        fit="results/{sample}/fit.json",
    output:
        html="results/{sample}/report.html",
        figure="results/{sample}/report.png",
    log:
        "results/logs/report/{sample}.log",
    shell:
        "dropfit report --trajectory {input.trajectory} --flights {input.flights}"
        " --impacts {input.impacts} --analysis {input.analysis} --fit {input.fit}"
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
