#!/usr/bin/env bash
# Third leg (issue 17): the shipped network (the 6000-step run of train-real.sh) trained on 256^2 crops - four times
# the context of its 128^2 crops - same data and PSF, Adam 2e-4 decaying over the leg; resumable.
cd "$(dirname "$0")/../../.."  # the repository root
start=runs/real-rank1-fast-6000.pt  # the shipped network when this leg started (commit 417f97e)
[ -f $start ] || { mkdir -p runs && git show 417f97e:hdrcam/checkpoints/simulated-rank1-fast.pt > $start; }
run=runs/real-rank1-fast-256
resume=""; [ -f $run/config.json ] && resume="--resume"  # a run claimed, saved or not
OMP_NUM_THREADS=${OMP_NUM_THREADS:-1} exec .venv/bin/hdrcam finetune --checkpoint $start \
  --psf tools/results/shipped-rank1/psf.exr \
  --data runs/data/train:0.6,procedural:0.3,../shared/data/hdr:0.1 \
  --steps 3500 --batch 2 --crop 256 --lr 2e-4 --seed 3 --checkpoint-every 250 --out $run $resume
