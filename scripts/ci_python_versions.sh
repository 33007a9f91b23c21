#!/usr/bin/env bash
# Python 3.12 and 3.13 in CI, besides the full test suite on 3.11 (issue #31; README "Python
# versions"). For each version, in parallel (one per core), with the interpreter the machine has:
#   1. a fresh venv (`python -m venv`) and the README's plain install, `python -m pip install .`,
#      from a copy of the source (pip builds the wheel; nothing is written into the clone);
#   2. from a folder outside the clone: the installed package is the venv's (not the clone's),
#      `skisnow solve` (the README's case, JSON with a positive real contact area), and
#      `skisnow serve` answering GET /readyz and one POST /v1/contact;
#   3. the test subset, existing tests run under this interpreter against the installed wheel:
#      tests/solvers/ (every numba kernel compiled and checked on this Python) but for the
#      identification's own tests, and the ski upload job to done
#      (tests/jobs/test_uploads.py::test_ski_upload_train_and_contact: upload, beam
#      identification, network training with the tests' small settings, a /v1/contact answer);
#      this needs pytest, httpx, hypothesis and torch (the `train` extra), installed only here.
# The interpreter of a version: $SKISNOW_CI_PYTHON_3_12 / _3_13 if set, else the newest
# $(pyenv root)/versions/3.12.x / 3.13.x, else python3.12 / python3.13 on PATH.
# Prints which interpreter ran each version and PASS/FAIL per step with timings; exits non-zero
# when any step of any version fails or a version's interpreter is missing.
#
# Usage: scripts/ci_python_versions.sh [VERSION ...]   (default: 3.12 3.13)
# Settings (environment): SKISNOW_CI_PYTHON_<X_Y> (interpreter of version X.Y),
# SKISNOW_CI_KEEP=1 (keep the work folder, printed at the end), SKISNOW_CI_PORT (8031: serve
# listens on this port + the version's index), SKISNOW_CI_PYTEST_ARGS (more pytest arguments
# for the subset, e.g. -x; CI sets none).
set -uo pipefail
cd "$(dirname "$0")/.." || exit 2
REPO=$PWD
VERSIONS=("$@")
[ ${#VERSIONS[@]} -gt 0 ] || VERSIONS=(3.12 3.13)
PORT0=${SKISNOW_CI_PORT:-8031}
T0=$SECONDS
WORK=$(mktemp -d /tmp/skisnow-pyversions.XXXXXX)
PIDS=()

log() { printf '[ci_python_versions %4d s] %s\n' $((SECONDS - T0)) "$*"; }

cleanup() {
    local pid
    for pid in "${PIDS[@]}"; do kill "$pid" 2>/dev/null; done
    if [ "${SKISNOW_CI_KEEP:-0}" = 1 ]; then
        log "work folder kept: $WORK"
    else
        rm -rf "$WORK"
    fi
}
trap cleanup EXIT

# the interpreter of version $1 (X.Y): the setting, the newest pyenv X.Y.z, or pythonX.Y
find_python() {
    local v=$1 var root cand
    var=SKISNOW_CI_PYTHON_${v//./_}
    if [ -n "${!var:-}" ]; then
        echo "${!var}"
        return
    fi
    root=$(pyenv root 2>/dev/null || echo "${PYENV_ROOT:-$HOME/.pyenv}")
    cand=$(find "$root/versions" -maxdepth 1 -name "$v.*" 2>/dev/null | grep -E "/$v\.[0-9]+$" |
        sort -V | tail -1)
    if [ -n "$cand" ] && [ -x "$cand/bin/python" ]; then
        echo "$cand/bin/python"
    else
        command -v "python$v" || echo "python$v"
    fi
}

# everything for version $1 with interpreter $2 and port $3, in folder $4; output to $4/log,
# one "PASS|FAIL  step (s)" line per step to $4/steps; exit status: 0 when all passed
run_version() {
    local v=$1 py=$2 port=$3 dir=$4 failed=0 t
    local venv=$dir/venv src=$dir/src out=$dir/outside bin
    bin=$venv/bin
    mkdir -p "$src" "$out" "$dir/data"
    step() {
        local name=$1
        shift
        t=$SECONDS
        echo "==== $name"
        if "$@"; then
            echo "PASS  $name ($((SECONDS - t)) s)" >>"$dir/steps"
        else
            echo "FAIL  $name ($((SECONDS - t)) s)" >>"$dir/steps"
            failed=1
        fi
    }
    # the environment of the commands: the venv's, no variable of the caller's (CI's) venv or
    # skisnow settings; its own numba cache and data folder
    local -a env=(env -u VIRTUAL_ENV -u PYTHONPATH -u PYTHONHOME -u SKISNOW_TABLES_DIR
        -u SKISNOW_DATABASE_URL PATH="$bin:$PATH" SKISNOW_DATA_DIR="$dir/data"
        NUMBA_CACHE_DIR="$dir/numba" MPLCONFIGDIR="$dir/mpl" PIP_DISABLE_PIP_VERSION_CHECK=1)

    install() {
        "$py" -m venv "$venv" || return 1
        # the image's pip of 3.12/3.13 is old (23.x, one warning per package about the local
        # package indexes); a failed upgrade is not an error (the old pip installs too)
        "${env[@]}" python -m pip install -q --upgrade pip >"$dir/pip-upgrade.log" 2>&1 ||
            echo "pip upgrade failed (see pip-upgrade.log); going on with $("$bin/python" -m pip -V)"
        tar -C "$REPO" --exclude=__pycache__ --exclude='*.pyc' --exclude=.checkpoints \
            -cf - pyproject.toml README.md app solvers tables | tar -C "$src" -xf - || return 1
        # the README's plain install
        (cd "$src" && "${env[@]}" python -m pip install -q .)
    }
    installed_outside() {
        # run from outside the clone: the package, its tables and its version are the venv's
        (cd "$out" && "${env[@]}" python - "$venv" <<'EOF'
import sys
from pathlib import Path

import skisnow.app as app
from skisnow.app.storage import common

venv = Path(sys.argv[1]).resolve()
where = Path(app.__file__).resolve()
tables = common.tables_dir().resolve()
print(f"python {sys.version.split()[0]}; skisnow from {where.parent}; tables {tables}")
assert where.is_relative_to(venv), f"skisnow imported from {where}, not from the venv {venv}"
assert tables.is_relative_to(venv), f"tables at {tables}, not the installed copy"
assert not common.is_source_checkout()
EOF
        )
    }
    solve() {
        (cd "$out" && "${env[@]}" skisnow solve --ski ski-a --grind grind-1 --load-kg 40 \
            --load-position-mm -160 --snow-modulus-mpa 200 --porosity 0.5 --json) >"$dir/solve.json" ||
            return 1
        "$bin/python" - "$dir/solve.json" <<'EOF'
import json
import sys

answer = json.load(open(sys.argv[1]))
area = answer["metrics"]["total_real_contact_area_mm2"]
print(f"skisnow solve: total real contact area {area:.4g} mm²")
assert area > 0, answer["metrics"]
EOF
    }
    serve() {
        local pid rc
        (cd "$out" && exec "${env[@]}" skisnow serve --host 127.0.0.1 --port "$port") \
            >"$dir/serve.log" 2>&1 &
        pid=$!
        echo "$pid" >"$dir/serve.pid"
        "$bin/python" - "$port" "$pid" <<'EOF'
import json
import os
import sys
import time
import urllib.error
import urllib.request

base = f"http://127.0.0.1:{sys.argv[1]}"
pid = int(sys.argv[2])
deadline = time.monotonic() + 180
while True:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        sys.exit("skisnow serve exited before it was ready (serve.log below)")
    try:
        with urllib.request.urlopen(f"{base}/readyz", timeout=5) as r:
            if r.status == 200:
                break
    except (urllib.error.URLError, ConnectionError, TimeoutError):
        pass
    if time.monotonic() > deadline:
        sys.exit("GET /readyz not 200 within 180 s")
    time.sleep(0.5)
body = {"ski": "ski-a", "grind": "grind-1", "load_kg": 40, "load_position_mm": -160,
        "snow_modulus_mpa": 200, "porosity": 0.5}
req = urllib.request.Request(f"{base}/v1/contact", data=json.dumps(body).encode(),
                             headers={"Content-Type": "application/json"})
with urllib.request.urlopen(req, timeout=120) as r:
    status, answer = r.status, json.loads(r.read())
area = answer["metrics"]["total_real_contact_area_mm2"]
print(f"POST /v1/contact: {status}, total real contact area {area:.4g} mm²")
assert status == 200 and area > 0, answer
EOF
        rc=$?
        kill "$pid" 2>/dev/null
        wait "$pid" 2>/dev/null
        [ "$rc" = 0 ] || tail -30 "$dir/serve.log"
        return "$rc"
    }
    test_deps() {
        # the versions pyproject.toml asks for: the `train` extra (torch) and, of the `test`
        # extra, what the subset imports; --no-compile: torch's byte-compilation is slow
        local -a reqs
        mapfile -t reqs < <("$bin/python" - "$src/pyproject.toml" <<'EOF'
import re
import sys
import tomllib

extras = tomllib.load(open(sys.argv[1], "rb"))["project"]["optional-dependencies"]
print(*extras["train"], sep="\n")
for req in extras["test"]:
    if re.split(r"[<>=!~\[; ]", req, maxsplit=1)[0].lower() in ("pytest", "httpx", "hypothesis"):
        print(req)
EOF
        )
        echo "test dependencies: ${reqs[*]}"
        [ ${#reqs[@]} -ge 4 ] && "${env[@]}" python -m pip install -q --no-compile "${reqs[@]}"
    }
    subset() {
        # the clone's tests against the installed wheel, in one process (the versions run in
        # parallel, one per core; pytest-xdist is not installed, so the project's addopts go).
        # Left out: the identification's own tests (pure numpy/scipy, several minutes; the
        # upload job identifies a ski's beam on this Python) and the ContactMechanics oracle
        # (skipped without it)
        # shellcheck disable=SC2086
        (cd "$REPO" && "${env[@]}" python -m pytest -q -p no:cacheprovider \
            -o addopts="--durations=10" tests/solvers --ignore=tests/solvers/test_identify.py \
            --ignore=tests/solvers/test_beam_fit.py --ignore=tests/solvers/test_micro_oracle.py \
            "tests/jobs/test_uploads.py::test_ski_upload_train_and_contact" \
            ${SKISNOW_CI_PYTEST_ARGS:-})
    }

    step "install: python -m venv + pip install ." install
    if [ $failed = 0 ]; then
        step "installed outside the clone" installed_outside
        step "skisnow solve" solve
        step "skisnow serve: /readyz + one /v1/contact answer" serve
        step "install test dependencies (pytest httpx hypothesis torch)" test_deps
        [ $failed = 0 ] && step "pytest tests/solvers + the ski upload job to done" subset
    fi
    return $failed
}

declare -A DIRS
i=0
for v in "${VERSIONS[@]}"; do
    i=$((i + 1))
    py=$(find_python "$v")
    DIRS[$v]=$WORK/py$v
    mkdir -p "${DIRS[$v]}"
    if ! actual=$("$py" -c 'import sys; print("%d.%d.%d" % sys.version_info[:3])' 2>/dev/null); then
        log "Python $v: interpreter missing: $py (not found or not runnable)"
        echo "FAIL  interpreter missing: $py (not found or not runnable)" >"${DIRS[$v]}/steps"
        continue
    fi
    if [ "${actual%.*}" != "$v" ]; then
        log "Python $v: $py is Python $actual"
        echo "FAIL  interpreter $py is Python $actual, not $v" >"${DIRS[$v]}/steps"
        continue
    fi
    log "Python $v: $py (Python $actual)"
    echo "Python $actual ($py)" >"${DIRS[$v]}/version"
    run_version "$v" "$py" $((PORT0 + i)) "${DIRS[$v]}" >"${DIRS[$v]}/log" 2>&1 &
    PIDS+=($!)
done
for pid in "${PIDS[@]}"; do wait "$pid"; done
PIDS=()

FAILED=0
for v in "${VERSIONS[@]}"; do
    dir=${DIRS[$v]}
    if grep -q "^FAIL" "$dir/steps" 2>/dev/null || [ ! -s "$dir/steps" ]; then
        FAILED=1
        if [ -s "$dir/log" ]; then
            echo "---- Python $v: log (last 60 lines; pip's warnings about the local indexes left out)"
            grep -v "^WARNING: Location" "$dir/log" | tail -60
        fi
    fi
done
echo "==== Python versions ($((SECONDS - T0)) s in all)"
for v in "${VERSIONS[@]}"; do
    dir=${DIRS[$v]}
    echo "-- Python $v: $(cat "$dir/version" 2>/dev/null || echo "not run")"
    if [ -s "$dir/steps" ]; then
        sed 's/^/   /' "$dir/steps"
    else
        echo "   FAIL  no step ran"
    fi
    # the tests' summary line (passed/failed counts)
    grep -E "^[0-9]+ (passed|failed)|^=+ .*(passed|failed)" "$dir/log" 2>/dev/null | tail -1 |
        sed 's/^/   pytest: /'
done
if [ $FAILED = 0 ]; then
    echo "PASS: Python ${VERSIONS[*]}"
else
    echo "FAIL: a claimed Python version failed (above)"
fi
exit $FAILED
