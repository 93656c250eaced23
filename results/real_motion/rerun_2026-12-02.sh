#!/bin/bash
# the real-motion suite again, with per-(scenario, robot) initial headings (3e79ecb) and episodes.csv (b83e129)
cd /work/main && . /work/venv/bin/activate
run() { echo "# $(date -u '+%Y-%m-%d %H:%M UTC'), at $(git rev-parse --short HEAD), nice -n 10"; echo "python evaluate.py $*"; nice -n 10 python evaluate.py "$@" > /dev/null || exit 1; }
run --suite real_motion --controller stand_still --out results/real_motion/stand_still_final_world --force
run --suite real_motion --checkpoint resources/policies/lasmp_a1.pt --out results/real_motion/lasmp_entropy0003_seed0_it999 --force
run --suite real_motion --checkpoint results/study/entropy_0/lasmp@1000/seed0/policy_999.pt --out results/real_motion/lasmp_entropy0_seed0_it999 --force
