#!/usr/bin/env bash
# Copy the screening results into results/screen/ (light: metrics, gzipped episode records, policy checkpoints)
cd "$(dirname "$0")/.."
. .venv/bin/activate
# an evaluation's record $1 (a path without .csv/.csv.gz) to $2, gzip-compressed: evaluate.py writes
# the .csv.gz itself; a plain .csv (an evaluation by an older evaluate.py) is compressed here
record() { if [ -e $1.csv.gz ]; then cp $1.csv.gz $2; else gzip -n -9 -c $1.csv > $2; fi; }
for d in runs/screen/*/seed*.done; do
  cand=$(basename $(dirname $d)); s=$(basename $d .done); src=runs/screen/$cand/$s; out=results/screen/$cand/$s
  [ -e $src.eval2000/metrics.json ] || continue
  mkdir -p $out
  cp $src.eval2000/metrics.json $out/metrics_2000.json; cp $src.eval2000/metrics.md $out/metrics_2000.md
  record $src.eval2000/episodes $out/episodes_2000.csv.gz
  cp $src/config.yaml $out/config.yaml; cp $src.commands $out/commands.txt
  [ -e $out/policy_449.pt ] || python -m lasmp.algo.checkpoint policy $src/model_449.pt $out/policy_449.pt > /dev/null
done
for m in runs/screen/mirror/*/seed*; do
  [ -e $m/metrics.json ] || continue
  out=results/screen/$(basename $(dirname $m))/$(basename $m); mkdir -p $out
  cp $m/metrics.json $out/mirror_1024.json; cp $m/metrics.md $out/mirror_1024.md
  record $m/episodes $out/episodes_1024.csv.gz; record $m/episodes_mirror $out/episodes_mirror_1024.csv.gz
done
