#!/usr/bin/env bash
# Mirror evaluation of the screening candidates and the LAS-MP baseline (first 1,024 Xi_eval episodes + twins)
cd "$(dirname "$0")/.."
. .venv/bin/activate
while [ ! -e runs/screen/sym_air/seed1.done ]; do sleep 10; done
for ck in results/study/lasmp/seed0/policy_449.pt:lasmp/seed0 runs/screen/sym_air/seed0/model_449.pt:sym_air/seed0 runs/screen/air_accrue/seed0/model_449.pt:air_accrue/seed0 results/study/lasmp/seed1/policy_449.pt:lasmp/seed1 runs/screen/sym_air/seed1/model_449.pt:sym_air/seed1 runs/screen/air_accrue/seed1/model_449.pt:air_accrue/seed1; do
  c=${ck%%:*}; name=${ck##*:}
  cmd="python evaluate.py --checkpoint $c --num-trajectories 1024 --mirror 1024 --no-platform-probe --out runs/screen/mirror/$name"
  echo "$(date -u +%FT%TZ) $cmd" >> runs/mirror.commands
  $cmd > /dev/null 2>> runs/mirror.err
done
echo "$(date -u +%FT%TZ) all done" >> runs/mirror.commands
