#!/usr/bin/env bash
# The one prepared command for a lent GPU machine: it measures the GPU's throughput, trains for
# a fixed number of minutes, evaluates what it trained and leaves everything in $OUT.
#
# A lent machine gives a task about 15 minutes of device time in all and at most 10 minutes a
# command, with no network and no pip index, so this script installs nothing from outside: it
# makes hkpd importable from the working tree (no build) and installs only the wheels carried
# in .whl/. docs/gpu_training.md says how to prepare and call it, and how to continue.
#
# Settings (environment variables, all optional):
#   OUT                   results folder (the device tool sets it; default runs/gpu_session_out)
#   HKPD_DEVICE           cuda (default) or cpu (for a rehearsal on a machine without a GPU)
#   HKPD_TRAIN_MINUTES    minutes of training steps (default 5)
#   HKPD_IMAGE_SIZE       proxy side in pixels (default 256, the paper's)
#   HKPD_WIDTH            ResNet-18 base width (default 48: fp16 weights of 20 MB fit the 25 MB
#                         committed-checkpoint limit; 64 is the paper's full width, 30 MB)
#   HKPD_BATCH_SIZE       examples per step and process (default 64)
#   HKPD_PROCESSES        training processes (default: every GPU torch sees, 1 on the CPU);
#                         more than 1 trains under torchrun with DistributedDataParallel, one
#                         GPU each, so a step takes HKPD_BATCH_SIZE x HKPD_PROCESSES examples
#   HKPD_INIT_WEIGHTS     weights to continue from (an earlier session's export); empty starts
#                         afresh with the paper's staged losses
#   HKPD_TRAIN_FLAGS      extra hkpd-train flags, appended last so they override the above
#   HKPD_BENCH            1 (default) runs the synthesis benchmark first, 0 skips it
#   HKPD_EVAL_COUNT       synthetic test examples for the closing evaluation (default 1000)
#   PYTHON                the interpreter (default python3)
# The run itself goes to runs/gpu_session/, which each call starts afresh.
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-runs/gpu_session_out}
DEVICE=${HKPD_DEVICE:-cuda}
MINUTES=${HKPD_TRAIN_MINUTES:-5}
IMAGE_SIZE=${HKPD_IMAGE_SIZE:-256}
WIDTH=${HKPD_WIDTH:-48}
BATCH=${HKPD_BATCH_SIZE:-64}
INIT=${HKPD_INIT_WEIGHTS:-}
BENCH=${HKPD_BENCH:-1}
EVAL_COUNT=${HKPD_EVAL_COUNT:-1000}
PYTHON=${PYTHON:-python3}
RUN=runs/gpu_session
export PYTHONUNBUFFERED=1
mkdir -p "$OUT"
started=$(date +%s)
stamp() { echo "[gpu_session +$(($(date +%s) - started)) s] $*"; }

if [ -z "${HKPD_PROCESSES:-}" ]; then
    if [ "$DEVICE" = cpu ]; then
        HKPD_PROCESSES=1
    else
        HKPD_PROCESSES=$("$PYTHON" -c "import torch; print(max(torch.cuda.device_count(), 1))")
    fi
fi
PROCESSES=$HKPD_PROCESSES
if [ "$PROCESSES" -gt 1 ]; then
    train=("$PYTHON" -m torch.distributed.run --standalone --nproc-per-node "$PROCESSES"
        -m hkpd.training.cli)
else
    train=("$PYTHON" -m hkpd.training.cli)
fi

if [ ! -f poses.npz ]; then
    echo "gpu_session: poses.npz is missing; build it here with" >&2
    echo "  hkpd-poses build ../shared/data/cmu_mocap/*/ --out poses.npz" >&2
    echo "and carry it (run(..., carry=[\"poses.npz\", \".whl\"]))" >&2
    exit 2
fi

# 1. The wheels the machine's image lacks (roma), carried in .whl/.
site=$(mktemp -d)
if compgen -G ".whl/*.whl" >/dev/null; then
    "$PYTHON" -m pip install -q --no-index --no-deps --no-compile --no-cache-dir \
        --target "$site/wheels" .whl/*.whl
fi
# 2. hkpd importable from the working tree, laid out as pyproject.toml installs it:
#    hkpd -> core/, hkpd.explorer -> explorer/, hkpd.assets -> assets/.
mkdir -p "$site/tree/hkpd"
for entry in core/*; do ln -s "$PWD/$entry" "$site/tree/hkpd/"; done
ln -s "$PWD/explorer" "$site/tree/hkpd/explorer"
ln -s "$PWD/assets" "$site/tree/hkpd/assets"
export PYTHONPATH="$site/tree:$site/wheels${PYTHONPATH:+:$PYTHONPATH}"
"$PYTHON" - <<'EOF' | tee "$OUT/environment.txt"
import platform, torch, numpy, hkpd
print(f"python {platform.python_version()}, torch {torch.__version__}, numpy {numpy.__version__}")
print(f"hkpd from {hkpd.__file__}")
if torch.cuda.is_available():
    print(f"{torch.cuda.device_count()} x GPU {torch.cuda.get_device_name(0)}, {torch.cuda.get_device_properties(0).total_memory / 2**30:.0f} GiB")
else:
    print("no GPU visible to torch")
EOF
command -v nvidia-smi >/dev/null && nvidia-smi --query-gpu=name,driver_version,memory.total \
    --format=csv >>"$OUT/environment.txt" || true

# 3. Throughput of synthetic data on one device (docs/benchmarks.md's "synthetic data on a GPU").
if [ "$BENCH" = 1 ]; then
    stamp "benchmark: synthetic data on $DEVICE"
    (cd benchmarks && "$PYTHON" bench_synthesis.py --device "$DEVICE" --poses ../poses.npz \
        --image-size "$IMAGE_SIZE" --batch-sizes 64 256 --repeats 3) | tee "$OUT/bench_synthesis.md"
fi

# 4. Train for the budget. Fresh: the paper's stages (mode 2D loss, then samples, then 3D
#    joints) with hkpd's concentration gain and limb boxes. Continued: every loss from step 0.
if [ -n "$INIT" ]; then
    stages=(--init-weights "$INIT" --samples-loss-from 0 --joints3d-loss-from 0
        --samples-loss-weight 4000 --learning-rate 1e-4)
else
    stages=(--samples-loss-from 1500 --joints3d-loss-from 3500 --learning-rate 2e-4)
fi
rm -rf "$RUN"
stamp "training for $MINUTES min: ${IMAGE_SIZE} px, width $WIDTH, batch $BATCH x $PROCESSES process(es), on $DEVICE"
# shellcheck disable=SC2086  # HKPD_TRAIN_FLAGS is a list of flags
"${train[@]}" --quiet --out "$RUN" --poses poses.npz --device "$DEVICE" \
    --image-size "$IMAGE_SIZE" --backbone-base-width "$WIDTH" --batch-size "$BATCH" \
    --steps 1000000 --max-minutes "$MINUTES" --concentration-gain \
    --limb-occlusion-probability 0.4 --val-every 1000 --val-size 200 --checkpoint-every 1000 \
    --log-every 50 "${stages[@]}" ${HKPD_TRAIN_FLAGS:-} 2>&1 | tee "$OUT/train_log.txt"
cp "$RUN"/config.json "$RUN"/train.csv "$RUN"/val.csv "$RUN"/curves.png "$OUT"/

# 5. Weights to keep (fp16), split into pieces the device tool brings back (16 MiB a file):
#    cat weights.pt.part* > weights.pt
"$PYTHON" -m hkpd.training.export "$RUN/last.pt" "$RUN/weights.pt"
split -b 15m -d "$RUN/weights.pt" "$OUT/weights.pt.part"

# 6. The card's synthetic and occlusion measures for what was trained.
stamp "evaluation"
"$PYTHON" -m hkpd.evaluation.cli "$RUN/weights.pt" --poses poses.npz --device "$DEVICE" \
    --count "$EVAL_COUNT" --occlusion-cases 100 --out "$OUT/eval.md"
stamp "done"
