#!/usr/bin/env bash
# Everything skisnow does on a GPU, in one run of a few minutes (issue #29; docs/tables.md
# "Light-load levels", docs/benchmarks.md "The micro solver on a GPU"):
#   1. the shipped grinds' light-load nodes (a_r 1e-4 … 1e-3) on finer levels down to 16384²
#      (`skisnow build-tables … --light-load-levels --device cuda`), tables into OUT/tables
#      (built in /tmp/tables: a killed pass leaves its checkpoints there, not in OUT);
#   2. the micro solver's benchmark, GPU against the CPU solver on the same machine's cores
#      (scripts/gpu_micro_bench.py), into OUT/gpu-micro.json and .png;
#   one log, OUT/session.log.
# Usage: OUT=dir GIT_COMMIT=sha bash scripts/gpu_session.sh [total budget s, default 540]
# On the lent GPU machine (no network, no pyFFTW, no sqlalchemy): carry .whl and this checkout;
# the script installs the wheels into /tmp/site. Made here (Python 3.12 wheels, ~8 MB):
#   echo /.whl/ >> .git/info/exclude; for w in pyFFTW==0.15.1 SQLAlchemy==2.1.9 alembic==1.20.1 \
#   Mako==1.4.3; do python3 -m pip download --no-deps --only-binary=:all: --python-version 3.12 \
#   --implementation cp --platform manylinux_2_28_x86_64 --platform manylinux2014_x86_64 -d .whl $w; done
# The working tree that travels is capped at 64 MiB: move docs/studies and tables/skis out for
# the run (neither is needed here) and back afterwards.
set -u -o pipefail
OUT=${OUT:?set OUT to the output directory}
BUDGET=${1:-540}
START=$(date +%s)
mkdir -p "$OUT/tables" /tmp/tables
LOG="$OUT/session.log"
if [ -z "${NO_WHEELS:-}" ] && [ -d .whl ] && ls .whl/*.whl >/dev/null 2>&1; then
    python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade \
        --target /tmp/site .whl/*.whl || exit 1
    export PYTHONPATH=/tmp/site:${PYTHONPATH:-}
fi
if ! python3 -c "import skisnow" 2>/dev/null; then  # this checkout as the package skisnow
    mkdir -p /tmp/pkg && ln -sfn "$PWD" /tmp/pkg/skisnow
    export PYTHONPATH=/tmp/pkg:${PYTHONPATH:-}
fi
export PYTHONUNBUFFERED=1
{
    date -u +%FT%TZ
    nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader || true
    python3 -c "import torch, numpy; print('torch', torch.__version__, 'cuda', torch.version.cuda, 'numpy', numpy.__version__)"
    nproc
} 2>&1 | tee "$LOG"
DEVICE=${DEVICE:-cuda}  # cpu: torch on the CPU (a smoke test of this script)
PASS_DEVICE=$([ "$DEVICE" = cuda ] && echo cuda || echo torch-cpu)
left() { echo $((BUDGET - ($(date +%s) - START))); }
light() {  # the light-load pass of one grind, if time is left
    t=$(left)
    [ "$t" -gt 60 ] || { echo "skipped $1 light-load levels: $t s left" | tee -a "$LOG"; return; }
    timeout "$((t - 20))" python3 -m skisnow.app.cli -v build-tables "$1" \
        --light-load-levels --from-table "tables/$1.h5" --out /tmp/tables \
        --finest-grid "${FINEST_GRID:-16384}" --device "$PASS_DEVICE" 2>&1 | tr '\r' '\n' | grep -v '^$' | tee -a "$LOG"
    cp /tmp/tables/"$1".h5 /tmp/tables/manifest.json "$OUT/tables/" 2>&1 | tee -a "$LOG"
}
light grind-2
t=$(left)
if [ "$t" -gt 60 ]; then  # at most BENCH_S (120 s): grind-1's pass comes after it
    b=$((t < ${BENCH_S:-120} ? t : ${BENCH_S:-120}))
    timeout "$b" python3 scripts/gpu_micro_bench.py --device "$DEVICE" \
        --sizes ${SIZES:-1024 2048 4096 8192 16384} --cpu-max-size "${CPU_MAX_SIZE:-4096}" \
        --gpu-repeats 3 --cpu-repeats 2 --ratio 1e-3 --time-budget-s "$((b - 30))" \
        --git-commit "${GIT_COMMIT:-unknown}" --out "$OUT/gpu-micro.json" \
        --chart "$OUT/gpu-micro.png" 2>&1 | tee -a "$LOG" | tail -n 40
else
    echo "skipped the benchmark: $t s left" | tee -a "$LOG"
fi
light grind-1
echo "total $(($(date +%s) - START)) s" | tee -a "$LOG"
