# the warm start's shock (docs/scaling.md): what ran, 2026-12-07 13:31-14:04 UTC, Intel(R) Xeon(R) Processor, 2 cores, with AVX-512 BF16,
# beside the ladder's base seed 10 run and the test suite
# --- /tmp/ws/run.sh
# does a warm start shock a trained policy? the same checkpoint (base seed 10, iteration 550) continued
# 49 iterations three ways: an exact resume, a warm start from its policy form (critic kept), and from
# its light form (no critic)
cd /work/main && . .venv/bin/activate
export TORCHINDUCTOR_CACHE_DIR=/tmp/ws/inductor
S=runs/warm_shock/base_seed10_light
python -m lasmp.algo.checkpoint policy $S/model_550.pt runs/warm_shock/policy_550.pt --force
python -m lasmp.light_checkpoint runs/warm_shock/policy_550.pt runs/warm_shock/light_550.pt --force
COMMON="runner.max_iterations=49 runner.validation_interval=25 runner.save_interval=49"
echo "=== A exact resume $(date -u +%H:%M)"; python train.py $COMMON resume=$S/model_550.pt runner.log_dir=runs/warm_shock/A_resume
echo "=== B warm policy $(date -u +%H:%M)"; python train.py $COMMON warm_start=runs/warm_shock/policy_550.pt runner.log_dir=runs/warm_shock/B_warm_policy
echo "=== C warm light $(date -u +%H:%M)"; python train.py $COMMON warm_start=runs/warm_shock/light_550.pt runner.log_dir=runs/warm_shock/C_warm_light
echo "=== done $(date -u +%H:%M)"
# --- /tmp/ws/runD.sh
# D: the warm start from the policy form that keeps the learning rate the schedule reached
cd /work/main && . .venv/bin/activate
while pgrep -f /tmp/ws/run.sh > /dev/null; do sleep 10; done
export TORCHINDUCTOR_CACHE_DIR=/tmp/ws/inductor
S=runs/warm_shock/base_seed10_light
python -m lasmp.algo.checkpoint policy $S/model_550.pt runs/warm_shock/policy_550_lr.pt --force
COMMON="runner.max_iterations=49 runner.validation_interval=25 runner.save_interval=49"
echo "=== D warm policy with its learning rate $(date -u +%H:%M)"; python train.py $COMMON warm_start=runs/warm_shock/policy_550_lr.pt runner.log_dir=runs/warm_shock/D_warm_policy_lr
echo "=== done $(date -u +%H:%M)"
# --- /tmp/ws/runE.sh
# E: the warm start from the light form (no critic) that keeps the learning rate the schedule reached
cd /work/main && . .venv/bin/activate
export TORCHINDUCTOR_CACHE_DIR=/tmp/ws/inductor
python -m lasmp.light_checkpoint runs/warm_shock/policy_550_lr.pt runs/warm_shock/light_550_lr.pt --force
COMMON="runner.max_iterations=49 runner.validation_interval=25 runner.save_interval=49"
echo "=== E warm light with its learning rate $(date -u +%H:%M)"; python train.py $COMMON warm_start=runs/warm_shock/light_550_lr.pt runner.log_dir=runs/warm_shock/E_warm_light_lr
echo "=== done $(date -u +%H:%M)"
