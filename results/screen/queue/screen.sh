#!/usr/bin/env bash
# Screening queue for the LAS-MP+ candidates (docs/screening.md): each line of runs/screen_queue.txt is "<candidate> <seed> <overrides...>".
# Trains 450 iterations with the learner PRECISION (default bfloat16; float32 on a CPU without
# AVX-512 bf16, where bfloat16 is 20x slower), then evaluates on Xi_eval's first 2,000 episodes and
# with the mirror evaluation on the first 1,024. Skips lines already done.
cd "$(dirname "$0")/.."
. .venv/bin/activate
PRECISION=${PRECISION:-bfloat16}
while true; do
  line=$(while read -r c s rest; do [ -z "$c" ] && continue; [ -e "runs/screen/$c/seed$s.done" ] || { echo "$c $s $rest"; break; }; done < runs/screen_queue.txt)
  [ -z "$line" ] && { sleep 30; continue; }
  read -r cand seed overrides <<< "$line"
  dir=runs/screen/$cand/seed$seed
  mkdir -p runs/screen/$cand
  cmd="python train.py algo.precision=$PRECISION seed=$seed runner.save_interval=150 runner.max_iterations=450 runner.log_dir=$dir $overrides"
  echo "$(date -u +%FT%TZ) $cmd" >> runs/screen/$cand/seed$seed.commands
  $cmd > runs/screen/$cand/seed$seed.train.log 2>&1 || { echo "train failed" >> runs/screen/$cand/seed$seed.commands; touch runs/screen/$cand/seed$seed.done; continue; }
  ev="python evaluate.py --checkpoint $dir/model_449.pt --num-trajectories 2000 --no-platform-probe --out runs/screen/$cand/seed$seed.eval2000"
  echo "$(date -u +%FT%TZ) $ev" >> runs/screen/$cand/seed$seed.commands
  $ev > runs/screen/$cand/seed$seed.eval.log 2>&1
  mv="python evaluate.py --checkpoint $dir/model_449.pt --num-trajectories 1024 --mirror 1024 --no-platform-probe --out runs/screen/mirror/$cand/seed$seed"
  echo "$(date -u +%FT%TZ) $mv" >> runs/screen/$cand/seed$seed.commands
  $mv > runs/screen/$cand/seed$seed.mirror.log 2>&1
  echo "$(date -u +%FT%TZ) done" >> runs/screen/$cand/seed$seed.commands
  touch runs/screen/$cand/seed$seed.done
done
