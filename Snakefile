# dropfit: ball drop tests to rebound heights, coefficient of restitution and ITF verdicts.
#
# Table of contents only; the rules live in workflow/rules/, one file per stage:
#   synth    data/synthetic/{scenario}.csv + .truth.json   synthetic drop tests with ground truth
#   synth_video  results/video/{clip}.avi + truth           synthetic drop-test videos
#   synth_audio  results/audio/table_tennis_40cm.wav + truth  synthetic drop-test sound
#   measure  results/{sample}/trajectory.nc (+ track.csv for a video)   recording -> SI trajectory
#   overlay  results/{sample}/contact_sheet.png             a video's tracked ball drawn on its frames
#   analyse  results/{sample}/{impacts,flights}.csv, analysis.json
#   fit      results/{sample}/fit.json                      restitution fit + ITF verdict
#   report   results/{sample}/report.{html,png}, results/batch/summary.{csv,html}
#   qc       results/batch/qc_{batch}.{html,png}, qc_{batch}_balls.csv   batch QC per batch of samples.tsv
#
# Run:  snakemake --profile workflow/profiles/default


from snakemake.utils import min_version

min_version("8.0")


configfile: "config/config.yaml"


include: "workflow/rules/common.smk"
include: "workflow/rules/synth.smk"
include: "workflow/rules/synth_video.smk"
include: "workflow/rules/synth_audio.smk"
include: "workflow/rules/measure.smk"
include: "workflow/rules/analyse.smk"
include: "workflow/rules/fit.smk"
include: "workflow/rules/report.smk"
include: "workflow/rules/qc.smk"


rule all:
    input:
        all_reports,
        "results/batch/summary.csv",
        "results/batch/summary.html",
        all_qc_reports,
