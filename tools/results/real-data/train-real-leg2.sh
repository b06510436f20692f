#!/usr/bin/env bash
# Leg 2: resume a copy of the 6000-step run to 8400 steps with the raw-camera-colour jitter (a80d402).
cd "$(dirname "$0")/../../.."  # the repository root
# the starting point: the procedural-only network shipped before this training (commit 47c155e)
start=runs/procedural-rank1-fast.pt
[ -f $start ] || { mkdir -p runs && git show 47c155e:hdrcam/checkpoints/simulated-rank1-fast.pt > $start; }
src=runs/real-rank1-fast; run=runs/real-rank1-fast-8400
if [ ! -d $run ]; then
  mkdir -p $run && cp $src/checkpoint.pt $src/log.jsonl $src/config.json $run/
fi
OMP_NUM_THREADS=1 exec .venv/bin/hdrcam finetune --checkpoint $start \
  --psf tools/results/shipped-rank1/psf.exr --data runs/data/train:0.6,procedural:0.3,../shared/data/hdr:0.1 \
  --steps 8400 --out $run --resume
