#!/usr/bin/env bash
# Seventh leg (issue 17): a night-leaning partner for the default pair - the leg-6 network (leg 3 + 3000 steps)
# trained 2000 more steps on 256^2 crops with more procedural night scenes (35 % photographs / 55 % procedural /
# 10 % openexr-images), same PSF, lr 1e-4; resumable.
cd "$(dirname "$0")/../../.."  # the repository root
start=runs/real-rank1-fast-leg6/model.pt  # made by train-real-leg6.sh
[ -f $start ] || { echo "run tools/results/real-data/train-real-leg6.sh first ($start is missing)" >&2; exit 1; }
run=runs/real-rank1-fast-leg7
resume=""; [ -f $run/config.json ] && resume="--resume"  # a run claimed, saved or not
OMP_NUM_THREADS=${OMP_NUM_THREADS:-1} exec .venv/bin/hdrcam finetune --checkpoint $start --no-partner \
  --psf tools/results/shipped-rank1/psf.exr \
  --data runs/data/train:0.35,procedural:0.55,../shared/data/hdr:0.1 \
  --steps 2000 --batch 2 --crop 256 --lr 1e-4 --seed 7 --checkpoint-every 250 --out $run $resume
