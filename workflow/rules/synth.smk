# Synthetic drop tests with exact ground truth, all scenarios of config["scenarios"] in one job (one
# Python process), written under results/ (data/synthetic/ holds the committed copies, which no rule
# writes).


rule synth:
    input:
        scenarios=config["scenarios"],
    output:
        logs=expand(f"{SYNTH_DIR}/{{scenario}}.csv", scenario=synthetic_recordings),
        truths=expand(f"{SYNTH_DIR}/{{scenario}}.truth.json", scenario=synthetic_recordings),
    log:
        "results/logs/synth/synth.log",
    conda:
        "../envs/dropfit.yaml"
    script:
        "../scripts/synth_logs.py"


# Recordings of the independent simulator refsim (no code shared with dropfit), e.g. the seed's Example 3
# of an oblique bounce sequence (x and y).
rule synth_refsim:
    output:
        log=f"{SYNTH_DIR}/{{refsim_scenario}}.csv",
        truth=f"{SYNTH_DIR}/{{refsim_scenario}}.truth.json",
    log:
        "results/logs/synth_refsim/{refsim_scenario}.log",
    conda:
        "../envs/dropfit.yaml"
    shell:
        "python -m refsim {wildcards.refsim_scenario} {output.log} --truth={output.truth} > {log} 2>&1"
