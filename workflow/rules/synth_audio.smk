# The bundled synthetic drop-test sound with its ground truth, rendered by the independent reference
# simulator (refsim/sound.py: clicks from refsim's bounce physics, echo, hum, noise, clipping); a few
# hundred kB, written under results/, never committed.


rule synth_audio:
    output:
        sound=f"{AUDIO_DIR}/table_tennis_40cm.wav",
        truth=f"{AUDIO_DIR}/table_tennis_40cm.truth.json",
    log:
        "results/logs/synth_audio/table_tennis_40cm.log",
    conda:
        "../envs/dropfit.yaml"
    shell:
        "python -m refsim.sound --out={output.sound} --truth={output.truth} > {log} 2>&1"
