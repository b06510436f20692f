#!/usr/bin/env bash
# Fine-tune the shipped rank-1 network on real photographs + procedural night scenes (issue 17); resumable.
cd "$(dirname "$0")/../../.."  # the repository root
# the starting point: the procedural-only network shipped before this training (commit 47c155e)
start=runs/procedural-rank1-fast.pt
[ -f $start ] || { mkdir -p runs && git show 47c155e:hdrcam/checkpoints/simulated-rank1-fast.pt > $start; }
run=runs/real-rank1-fast
resume=""; [ -f $run/config.json ] && resume="--resume"  # a run claimed, saved or not
OMP_NUM_THREADS=1 exec .venv/bin/hdrcam finetune --checkpoint $start \
  --psf tools/results/shipped-rank1/psf.exr \
  --data runs/data/train:0.6,procedural:0.3,../shared/data/hdr:0.1 \
  --steps 6000 --batch 4 --crop 128 --lr 5e-4 --seed 0 --checkpoint-every 250 --out $run $resume
