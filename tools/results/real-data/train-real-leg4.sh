#!/usr/bin/env bash
# Fourth leg (issue 17): does a smaller share of procedural night scenes (bright lamps) make the network paint
# fewer highlights into windows barely above white? The shipped network trained 3000 more steps on 128^2 crops
# with 80 % photographs / 10 % procedural / 10 % openexr-images (shipped: 60 / 30 / 10), same PSF; resumable.
cd "$(dirname "$0")/../../.."  # the repository root
start=runs/real-rank1-fast-6000.pt  # the shipped network (unchanged since commit 417f97e)
[ -f $start ] || { mkdir -p runs && git show 417f97e:hdrcam/checkpoints/simulated-rank1-fast.pt > $start; }
run=runs/real-rank1-fast-leg4
resume=""; [ -f $run/config.json ] && resume="--resume"  # a run claimed, saved or not
OMP_NUM_THREADS=${OMP_NUM_THREADS:-1} exec .venv/bin/hdrcam finetune --checkpoint $start \
  --psf tools/results/shipped-rank1/psf.exr \
  --data runs/data/train:0.8,procedural:0.1,../shared/data/hdr:0.1 \
  --steps 3000 --batch 4 --crop 128 --lr 2e-4 --seed 4 --checkpoint-every 250 --out $run $resume
