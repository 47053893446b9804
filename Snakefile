# dropfit: ball drop tests to rebound heights, coefficient of restitution and ITF verdicts.
#
# Table of contents only; the rules live in workflow/rules/:
#   synth        results/synthetic/{scenario}.csv + .truth.json   synthetic drop tests with ground truth
#   synth_video  results/video/{clip}.avi + truth                 synthetic drop-test videos
#   synth_audio  results/audio/table_tennis_40cm.wav + truth      synthetic drop-test sound
#   process_*    results/{sample}/trajectory.nc, impacts.csv, flights.csv, analysis.json, fit.json,
#                report.{html,png} (a video also track.csv, contact_sheet.png); a chunk of recordings a job
#   summary      results/batch/summary.{csv,html}, summary_extras.png
#   qc           results/batch/qc_{batch}.{html,png}, qc_{batch}_balls.csv   batch QC per batch of samples.tsv
#
# Run:  snakemake --profile workflow/profiles/default
# The run ends with the failed recordings and their reasons, and exit status 1 if there are any
# (config fail_on_failed_recordings).


from snakemake.utils import min_version

min_version("8.0")


configfile: "config/config.yaml"


report: "workflow/report/workflow.rst"


include: "workflow/rules/common.smk"
include: "workflow/rules/synth.smk"
include: "workflow/rules/synth_video.smk"
include: "workflow/rules/synth_audio.smk"
include: "workflow/rules/process.smk"
include: "workflow/rules/report.smk"
include: "workflow/rules/qc.smk"


rule all:
    default_target: True
    input:
        all_reports,
        "results/batch/summary.csv",
        "results/batch/summary.html",
        all_qc_reports,


onstart:
    remove_leftovers()


onsuccess:
    list_failed_recordings()


onerror:
    list_failed_recordings()
