#!/usr/bin/env bash
# The speed-accuracy trade of the presets at equal CPU time (issue 17, deliver 2): `fast` and `lite` each trained
# from scratch for about 22 minutes on one thread behind the shipped PSF, on the same data mix as train-real.sh
# (fast: 0.65 s a step -> 2000 steps; lite: 2.5x the step time -> 800 steps); scored with `hdrcam evaluate
# --no-partner` (tools/results/real-data/README.md, "The presets at equal CPU time").
# `paper` (24x the step time) would take 80 steps in that time and needs VGG-19 weights: not run. Resumable.
cd "$(dirname "$0")/../../.."  # the repository root
for spec in fast:2000 lite:800; do
  preset=${spec%%:*}; steps=${spec#*:}; run=runs/preset-$preset
  resume=""; [ -f $run/config.json ] && resume="--resume"  # a run claimed, saved or not
  OMP_NUM_THREADS=${OMP_NUM_THREADS:-1} .venv/bin/hdrcam design --preset $preset \
    --psf tools/results/shipped-rank1/psf.exr --data runs/data/train:0.6,procedural:0.3,../shared/data/hdr:0.1 \
    --steps $steps --batch 4 --crop 128 --lr 5e-4 --seed 0 --checkpoint-every 100 --out $run $resume || exit 1
done
