#!/bin/bash
# The GPU run, as one command on the lent machine (docs/gpu.md, "Training on a GPU"): join warp-lang's wheel
# parts, install the wheels the machine lacks (no registry; nothing when they import already), the Go2 throughput
# sweep (SWEEP_SECONDS, 100), FR-Net training with the one training env (frbench.training.env) on MuJoCo Warp on
# the device, built from the Go2 bundle, for TRAIN_SECONDS of wall clock (330), the G1 sweep (SWEEP_G1_SECONDS, 60), then
# the checkpoint, curve.csv, throughput-*.json and report.md in $OUT: about 9.5 minutes in all, inside one
# 10-minute device call (timeout_s 590).
#
#   bash tools/gpu_run/run.sh            # in the repository root of the lean tree, $OUT set by the device tool
#
# Expects runs/gpu_payload/{go2,g1,wheels} (tools/gpu_run/make_bundle.py; wheels/ without warp-lang's parts,
# which earlier calls left in runs/stash/). TRAIN_SECONDS (default 330) bounds the training's wall clock;
# DEVICE (cuda), SWEEP_ENVS (256,1024,4096,8192), TRAIN_FLAGS_FILE (tools/gpu_run/train_flags.txt) and
# PAYLOAD (runs/gpu_payload) and EXTRA_PYTHONPATH (appended to PYTHONPATH) exist for a dry run on a CPU (docs/gpu.md).
set -euo pipefail
P=${PAYLOAD:-runs/gpu_payload}
DEVICE=${DEVICE:-cuda}
FLAGS=$(cat "${TRAIN_FLAGS_FILE:-tools/gpu_run/train_flags.txt}")
OUT=${OUT:-/tmp/gpu-out}
rm -rf /tmp/gpu-site && mkdir -p "$OUT" /tmp/gpu-site
start=$(date +%s)
log() { echo "[$(( $(date +%s) - start )) s] $*" | tee -a "$OUT/report.md"; }
echo "# GPU run ($(date -u +%FT%TZ))" > "$OUT/report.md"
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader | tee -a "$OUT/report.md" || true
if python -c 'import warp, mujoco, mujoco_warp, rsl_rl, tensordict, array_api_compat' 2>/dev/null; then
    log "the packages are installed already (a dry run): nothing to install"
else
    WARP_WHEEL=/tmp/$(cat runs/stash/warp_lang.name 2>/dev/null || cat $P/wheels/warp_lang.name)
    cat runs/stash/warp_lang.whl.part-* > "$WARP_WHEEL" 2>/dev/null || cat $P/wheels/warp_lang.whl.part-* > "$WARP_WHEEL"
    python -m pip install --quiet --no-index --no-deps --target /tmp/gpu-site "$WARP_WHEEL" $P/wheels/*.whl
fi
export PYTHONPATH=$PWD:/tmp/gpu-site${EXTRA_PYTHONPATH:+:$EXTRA_PYTHONPATH} GIT_PYTHON_REFRESH=quiet  # GitPython without git
log "installed: $(python -c 'import warp, mujoco, mujoco_warp, rsl_rl, tensordict; print("warp", warp.__version__, "mujoco", mujoco.__version__, "rsl_rl ok")')"
sweep() {  # sweep ROBOT SECONDS: one robot's rows of the throughput sweep (kept as they come if the time runs out)
    log "throughput sweep: $1 (<= $2 s, first use compiles Warp's kernels for its model)"
    timeout "$2" python benchmarks/gpu_throughput.py --device "$DEVICE" --robots "$1" \
        --envs "${SWEEP_ENVS:-256,1024,4096,8192}" --steps "${SWEEP_STEPS:-50}" --iterations 1 --bundle $P/go2 \
        --bundle-g1 $P/g1 --out "$OUT/throughput-$1.json" >> "$OUT/throughput.log" 2>&1 || log "sweep $1: exit $?"
    grep '^{' "$OUT/throughput.log" | grep "\"robot\": \"$1\"" >> "$OUT/report.md" || true
}
sweep go2 "${SWEEP_SECONDS:-100}"
log "training for ${TRAIN_SECONDS:-330} s: frbench train $FLAGS --device $DEVICE"
timeout -s INT "${TRAIN_SECONDS:-330}" python -m frbench train $FLAGS --device "$DEVICE" \
    --bundle $P/go2 --steps 5e9 --checkpoint-every 10 --out "$OUT/run" > "$OUT/train.log" 2>&1 || log "train: exit $? (the wall-clock budget ends it; the last checkpoint stands)"
sweep g1 "${SWEEP_G1_SECONDS:-60}"
tail -c 2000 "$OUT/train.log" | tr '\r' '\n' | tail -5 >> "$OUT/report.md"
[ -f "$OUT/run/curve.csv" ] && cp "$OUT/run/curve.csv" "$OUT/curve.csv"
python - "$OUT" >> "$OUT/report.md" <<'PY'
import csv, json, sys, pathlib
out = pathlib.Path(sys.argv[1])
rows = list(csv.DictReader(open(out / "curve.csv"))) if (out / "curve.csv").exists() else []
if rows:
    last = rows[-1]
    print(f"trained {int(last['env_steps']) / 1e6:.1f} M env steps in {float(last['wall_s']):.0f} s "
          f"({int(last['env_steps']) / max(float(last['wall_s']), 1e-9):.0f} env steps/s with PPO); "
          f"success_all {last.get('success_all')}, mean_level {last.get('mean_level')}")
else:
    print("no checkpoint written")
PY
log "done"
