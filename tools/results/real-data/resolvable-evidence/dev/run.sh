#!/usr/bin/env bash
# usage: run.sh SMAX   (development runs of the resolvable-evidence candidate from the worktree)
set -u
S=$1; O=/work/scratch/res/s$S; mkdir -p $O
export OMP_NUM_THREADS=1 HDRCAM_SMAX=$S
cd /work/scratch/wt-res
P=/work/main/.venv/bin/python
for v in 1 2 3 4 5 6; do $P -m hdrcam evaluate --data /work/scratch/stress/v$v --size 512 --out $O/v$v > $O/v$v.log 2>&1; done
$P -m hdrcam evaluate --data /work/main/runs/data/train --size 512 --out $O/train > $O/train.log 2>&1
$P -m hdrcam evaluate --data /work/scratch/nightgen/dev11 --size 512 --out $O/ind11 > $O/ind11.log 2>&1
$P -m hdrcam evaluate --data procedural --count 32 --out $O/night32 > $O/night32.log 2>&1
touch $O/done
