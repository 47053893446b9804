# Synthetic drop tests with exact ground truth, one job per scenario of config["scenarios"].


rule synth:
    input:
        scenarios=config["scenarios"],
    output:
        log="data/synthetic/{scenario}.csv",
        truth="data/synthetic/{scenario}.truth.json",
    log:
        "results/logs/synth/{scenario}.log",
    shell:
        "dropfit synth --scenarios {input.scenarios} --name {wildcards.scenario}"
        " --log {output.log} --truth {output.truth} > {log} 2>&1"
