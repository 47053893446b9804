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


# Recordings of the independent simulator refsim (no code shared with dropfit), e.g. the seed's Example 3
# of an oblique bounce sequence (x and y); committed like the logs above, remade here when missing.
rule synth_refsim:
    output:
        log="data/synthetic/{refsim_scenario}.csv",
        truth="data/synthetic/{refsim_scenario}.truth.json",
    log:
        "results/logs/synth_refsim/{refsim_scenario}.log",
    shell:
        "python -m refsim {wildcards.refsim_scenario} {output.log} --truth {output.truth} > {log} 2>&1"
