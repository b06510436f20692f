#!/usr/bin/env bash
# Sixth leg (issue 17): the leg-3 network (256^2 crops, 3500 steps) trained 3000 more steps the same way - 256^2
# crops, leg 3's mixture (60 % photographs / 30 % procedural / 10 % openexr-images), same PSF - at half leg 3's
# learning rate; resumable.
cd "$(dirname "$0")/../../.."  # the repository root
start=runs/real-rank1-fast-256/model.pt  # made by train-real-leg3.sh
[ -f $start ] || { echo "run tools/results/real-data/train-real-leg3.sh first ($start is missing)" >&2; exit 1; }
run=runs/real-rank1-fast-leg6
resume=""; [ -f $run/config.json ] && resume="--resume"  # a run claimed, saved or not
OMP_NUM_THREADS=${OMP_NUM_THREADS:-1} exec .venv/bin/hdrcam finetune --checkpoint $start \
  --psf tools/results/shipped-rank1/psf.exr \
  --data runs/data/train:0.6,procedural:0.3,../shared/data/hdr:0.1 \
  --steps 3000 --batch 2 --crop 256 --lr 1e-4 --seed 6 --checkpoint-every 250 --out $run $resume
