#!/usr/bin/env bash
# Table 2 of the paper at the A7's scale (profile sony-a7-zeiss50-rank1, chirp-z optics, 255 px PSFs), on a CPU.
# Two stages, the same for every row:
#   1. optics: the learned rows (rank1, freeform) get a PSF-first design (tools/design_psf_first.py; the CPU cannot
#      afford the joint optimisation at this scale), simulated at 7 sub-pixels by `hdrcam psf`; dirac, star8 and
#      dual-peak are the paper's hand-designed patterns imaged through the same bare lens;
#   2. network: `hdrcam design --psf` from the same starting network (the shipped fast network), same data, steps,
#      batch, crop, learning rate and seed for every row.
# Usage: bash tools/results/table2/train-table2.sh NAMES [STEPS]   (NAMES: comma list of rank1,freeform,dirac,star8,
# dual-peak). Re-running continues interrupted runs (--resume) and skips finished ones; run two shells with
# different NAMES on a 2-core machine. Needs runs/data (tools/split_hdr_train.py ../shared/data/hdr-train --out runs/data).
set -euo pipefail
cd "$(dirname "$0")/../../.."  # the repository root
names="${1:?NAMES}"
steps="${2:-800}"
runs=runs/table2
profile=sony-a7-zeiss50-rank1
start=runs/table2-start.pt  # the shipped network when this table was made (commit 34b789a)
[ -f $start ] || { mkdir -p runs && git show 34b789a:hdrcam/checkpoints/simulated-rank1-fast.pt > $start; }
export OMP_NUM_THREADS=1
for name in ${names//,/ }; do
  psf=$name
  if [[ $name == rank1 || $name == freeform ]]; then
    [ -f $runs/$name-optics/heightmap.exr ] || .venv/bin/python tools/design_psf_first.py --profile $profile \
      --doe $name --steps 30 --seed 0 --out $runs/$name-optics
    [ -f $runs/$name-psf/psf.exr ] || .venv/bin/hdrcam psf --profile $profile --doe $runs/$name-optics/heightmap.exr \
      --out $runs/$name-psf
    psf=$runs/$name-psf/psf.exr
  fi
  [ -f $runs/$name/model.pt ] && continue
  resume=(); [ -f $runs/$name/config.json ] && resume=(--resume)  # a run claimed, saved or not
  .venv/bin/hdrcam design --profile $profile --psf "$psf" --init $start --preset fast \
    --data runs/data/train:0.6,procedural:0.3,../shared/data/hdr:0.1 \
    --steps "$steps" --batch 4 --crop 128 --lr 2e-4 --seed 0 --checkpoint-every 100 --out $runs/$name "${resume[@]}"
done
