#!/usr/bin/env bash
# Fifth leg (issue 17): legs 3 and 4 combined - the leg-3 network (256^2 crops, 3500 steps) trained 3000 more steps
# on 256^2 crops with leg 4's mixture (80 % photographs / 10 % procedural / 10 % openexr-images), same PSF;
# resumable.
cd "$(dirname "$0")/../../.."  # the repository root
start=runs/real-rank1-fast-256/model.pt  # made by train-real-leg3.sh
[ -f $start ] || { echo "run tools/results/real-data/train-real-leg3.sh first ($start is missing)" >&2; exit 1; }
run=runs/real-rank1-fast-leg5
resume=""; [ -f $run/config.json ] && resume="--resume"  # a run claimed, saved or not
OMP_NUM_THREADS=${OMP_NUM_THREADS:-1} exec .venv/bin/hdrcam finetune --checkpoint $start \
  --psf tools/results/shipped-rank1/psf.exr \
  --data runs/data/train:0.8,procedural:0.1,../shared/data/hdr:0.1 \
  --steps 3000 --batch 2 --crop 256 --lr 2e-4 --seed 5 --checkpoint-every 250 --out $run $resume
