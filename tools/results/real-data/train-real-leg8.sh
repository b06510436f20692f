#!/usr/bin/env bash
# Eighth leg (issue 17): a bolder night partner - the leg-7 network (the shipped partner)
# trained 2500 more steps on 256^2 crops with still more procedural night scenes (25 % photographs / 70 % procedural /
# 5 % openexr-images), same PSF, lr 1e-4; resumable.
cd "$(dirname "$0")/../../.."  # the repository root
start=runs/real-rank1-fast-leg7/model.pt  # made by train-real-leg7.sh
[ -f $start ] || { echo "run tools/results/real-data/train-real-leg7.sh first ($start is missing)" >&2; exit 1; }
run=runs/real-rank1-fast-leg8
resume=""; [ -f $run/config.json ] && resume="--resume"  # a run claimed, saved or not
OMP_NUM_THREADS=${OMP_NUM_THREADS:-1} exec .venv/bin/hdrcam finetune --checkpoint $start --no-partner \
  --psf tools/results/shipped-rank1/psf.exr \
  --data runs/data/train:0.25,procedural:0.7,../shared/data/hdr:0.05 \
  --steps 2500 --batch 2 --crop 256 --lr 1e-4 --seed 8 --checkpoint-every 250 --out $run $resume
