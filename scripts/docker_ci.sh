#!/usr/bin/env bash
# Build the Docker image and run it as a deployment would (issue #15 point 3; docs/deployment.md).
#
# Needs root (it installs docker.io and debootstrap when missing and may start dockerd). Steps:
#   1. a Docker daemon: the running one, else `dockerd --iptables=false --bridge=none` started
#      here and stopped at the end (containers therefore use --network host);
#   2. the base image python:3.11-slim: the local one if present, else a stand-in made with
#      debootstrap (Debian bookworm, python 3.11) from the machine's apt mirror, with the
#      machine's CA bundle; kept for the next run;
#   3. docker build; then checks on containers of the image: /readyz, one /v1/contact answer, the
#      health status turning healthy, uid/gid 10001, tables read-only, an uploaded grind
#      surviving `docker restart`, every package at its version in scripts/docker-constraints.txt,
#      `skisnow macro` and `skisnow micro` on the shipped data, and
#      10 fresh starts on new empty volumes (in parallel) each ready and still running after 30 s;
#   4. removes its containers, volumes and the image skisnow:ci (the base image and the build
#      cache, i.e. the image's parent layers, stay, so the next run builds only what changed).
# Prints PASS/FAIL per check with timings; exits non-zero if any check failed.
#
# Settings (environment): SKISNOW_CI_PORT (8011), SKISNOW_CI_FRESH (10 fresh starts),
# SKISNOW_CI_KEEP_IMAGE=1 (keep skisnow:ci), SKISNOW_CI_MIRROR (apt mirror for debootstrap).
set -euo pipefail
cd "$(dirname "$0")/.."

IMAGE=skisnow:ci
BASE=python:3.11-slim
PORT=${SKISNOW_CI_PORT:-8011}
FRESH=${SKISNOW_CI_FRESH:-10}
FRESH_PORT0=$((PORT + 10)) # fresh starts on PORT+11 ... PORT+10+FRESH
NAME=skisnow-ci-$$         # prefix of every container and volume made here
LABEL=skisnow-ci=$$
T0=$SECONDS
TMP=$(mktemp -d /tmp/skisnow-docker-ci.XXXXXX)
DOCKERD_PID=
RESULTS=()
FAILED=0
BUILT=0

log() { printf '[docker_ci %4d s] %s\n' $((SECONDS - T0)) "$*"; }

# run "$@" as the check named $1 (the rest is the command); record PASS/FAIL and its time
check() {
    local name=$1 t=$SECONDS
    shift
    log "check: $name"
    if "$@"; then
        RESULTS+=("PASS  $name ($((SECONDS - t)) s)")
    else
        RESULTS+=("FAIL  $name ($((SECONDS - t)) s)")
        FAILED=1
    fi
}

cleanup() {
    local rc=$?
    set +e
    local ids
    ids=$(docker ps -aq --filter "label=$LABEL" 2>/dev/null)
    if [ -n "$ids" ]; then
        if [ "$FAILED" = 1 ] || [ "$rc" != 0 ]; then
            for c in $ids; do
                echo "---- logs of $(docker inspect -f '{{.Name}}' "$c") (last 30 lines)"
                docker logs --tail 30 "$c" 2>&1
            done
        fi
        # shellcheck disable=SC2086
        docker rm -f $ids >/dev/null
    fi
    ids=$(docker volume ls -q --filter "label=$LABEL" 2>/dev/null)
    # shellcheck disable=SC2086
    [ -n "$ids" ] && docker volume rm $ids >/dev/null
    if [ "$BUILT" = 1 ] && [ "${SKISNOW_CI_KEEP_IMAGE:-0}" != 1 ]; then
        # the image goes; its parent layers stay as the build cache (a full rmi deletes the
        # runtime stage's layers, and the next run copies the 700 MB venv again: 20 s)
        docker rmi --no-prune "$IMAGE" >/dev/null
    fi
    if [ -n "$DOCKERD_PID" ]; then
        kill "$DOCKERD_PID" 2>/dev/null
        for _ in $(seq 60); do kill -0 "$DOCKERD_PID" 2>/dev/null || break; sleep 0.5; done
        kill -0 "$DOCKERD_PID" 2>/dev/null && kill -9 "$DOCKERD_PID"
    fi
    rm -rf "$TMP"
    echo "==== docker_ci summary"
    printf '%s\n' "${RESULTS[@]}"
    echo "total $((SECONDS - T0)) s"
    if [ "$rc" != 0 ]; then
        echo "docker_ci: FAIL (stopped with exit code $rc before the end)"
    elif [ "$FAILED" = 1 ]; then
        echo "docker_ci: FAIL"
        rc=1
    else
        echo "docker_ci: PASS"
    fi
    exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

step() { # a setup step that must succeed; recorded with its time
    local name=$1 t=$SECONDS
    shift
    log "step: $name"
    "$@"
    RESULTS+=("done  $name ($((SECONDS - t)) s)")
}

# ---------------------------------------------------------------- 1. tools and daemon
install_tools() {
    if ! command -v dockerd >/dev/null || ! command -v debootstrap >/dev/null; then
        apt-get update -qq
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq docker.io debootstrap >/dev/null
    fi
}

start_daemon() {
    if docker info >/dev/null 2>&1; then
        log "using the running Docker daemon"
        return
    fi
    dockerd --iptables=false --bridge=none --pidfile "$TMP/dockerd.pid" \
        >"$TMP/dockerd.log" 2>&1 &
    DOCKERD_PID=$!
    for _ in $(seq 120); do
        docker info >/dev/null 2>&1 && return
        kill -0 "$DOCKERD_PID" 2>/dev/null || break
        sleep 0.5
    done
    tail -20 "$TMP/dockerd.log"
    echo "dockerd did not start" >&2
    return 1
}

# ---------------------------------------------------------------- 2. base image
apt_mirror() { # the Debian mirror the machine's apt uses (deb822 or one-line sources)
    if [ -n "${SKISNOW_CI_MIRROR:-}" ]; then
        echo "$SKISNOW_CI_MIRROR"
        return
    fi
    local f uri
    for f in /etc/apt/sources.list.d/*.sources /etc/apt/sources.list /etc/apt/sources.list.d/*.list; do
        [ -f "$f" ] || continue
        uri=$(awk '
            /^[ \t]*#/ { next }
            /^URIs:/ { u = $2 }
            /^Suites:/ { for (i = 2; i <= NF; i++) if ($i == "bookworm" && u != "") { print u; exit } }
            /^deb[ \t]/ { s = ($2 ~ /^\[/) ? 4 : 3; if ($s == "bookworm") { print $(s - 1); exit } }
        ' "$f")
        if [ -n "$uri" ]; then
            echo "$uri"
            return
        fi
    done
    echo http://deb.debian.org/debian
}

make_base() {
    if docker image inspect "$BASE" >/dev/null 2>&1; then
        log "base image $BASE present"
        return
    fi
    local mirror rootfs=$TMP/rootfs
    mirror=$(apt_mirror)
    log "base image $BASE: debootstrap bookworm from $mirror"
    debootstrap --variant=minbase \
        --include=python3,python3-venv,python3-pip,python-is-python3,ca-certificates \
        bookworm "$rootfs" "$mirror" >"$TMP/debootstrap.log" 2>&1 || {
        tail -20 "$TMP/debootstrap.log"
        return 1
    }
    # the machine's CA bundle (a TLS-inspecting egress proxy signs PyPI's certificate) and pip
    # told to use it (pip otherwise trusts only its own bundle)
    cp /etc/ssl/certs/ca-certificates.crt "$rootfs/etc/ssl/certs/ca-certificates.crt"
    printf '[global]\ncert = /etc/ssl/certs/ca-certificates.crt\n' >"$rootfs/etc/pip.conf"
    rm -rf "$rootfs"/var/cache/apt/archives/*.deb "$rootfs"/var/lib/apt/lists/*
    tar -C "$rootfs" -c . | docker import --change 'ENV LANG=C.UTF-8' \
        --change 'CMD ["python3"]' - "$BASE" >/dev/null
    rm -rf "$rootfs"
}

build_image() {
    docker build --network host -t "$IMAGE" . >"$TMP/build.log" 2>&1 || {
        tail -40 "$TMP/build.log"
        return 1
    }
    grep -c 'Using cache' "$TMP/build.log" | xargs printf '%s build steps from the cache\n'
}

# ---------------------------------------------------------------- helpers for the checks
url() { echo "http://127.0.0.1:$1$2"; }

ports_free() { # refuse ports another process listens on (its /readyz would answer for ours)
    local p
    for p in "$@"; do
        if (exec 3<>"/dev/tcp/127.0.0.1/$p") 2>/dev/null; then
            echo "port $p is in use on this machine: set SKISNOW_CI_PORT" >&2
            return 1
        fi
    done
}

wait_ready() { # wait_ready PORT CONTAINER TIMEOUT_S: /readyz answers 200 while the container runs
    local port=$1 c=$2 timeout=$3 t=$SECONDS
    while [ $((SECONDS - t)) -lt "$timeout" ]; do
        if curl -fsS -o /dev/null --max-time 2 "$(url "$port" /readyz)" 2>/dev/null; then
            return 0
        fi
        if [ "$(docker inspect -f '{{.State.Running}}' "$c")" != true ]; then
            echo "$c stopped: $(docker inspect -f 'exit code {{.State.ExitCode}}' "$c")" >&2
            return 1
        fi
        sleep 1
    done
    echo "$c: /readyz did not answer in $timeout s" >&2
    return 1
}

json_get() { # json_get EXPR: evaluate EXPR on the JSON document `d` read from stdin
    python3 -c "import json, sys; d = json.load(sys.stdin); print($1)"
}

MAIN=$NAME-main
run_main() { # the service with a non-default port, a named volume and a short health interval
    ports_free "$PORT" $(seq $((FRESH_PORT0 + 1)) $((FRESH_PORT0 + FRESH)))
    docker volume create --label "$LABEL" "$NAME-data" >/dev/null
    # small table builds so the upload's job takes seconds (settings of tests/jobs/test_uploads.py)
    docker run -d --name "$MAIN" --label "$LABEL" --network host \
        -e SKISNOW_PORT="$PORT" -e SKISNOW_TABLE_POINTS=8 -e SKISNOW_TABLE_PROCESSES=false \
        -v "$NAME-data:/srv/skisnow/data" \
        --health-interval 2s --health-start-period 120s >/dev/null "$IMAGE"
}

check_ready() { wait_ready "$PORT" "$MAIN" 180; }

check_contact() {
    local body
    body=$(curl -fsS --max-time 60 "$(url "$PORT" /v1/contact)" \
        -H 'content-type: application/json' \
        -d '{"ski": "ski-a", "grind": "grind-1", "load_kg": 40, "load_position_mm": -160,
             "snow_modulus_mpa": 200, "porosity": 0.5, "ski_model": "rigid"}') || return 1
    echo "$body" | json_get "'apparent area', d['apparent']['contact_area_cm2'], 'cm2; real area', \
        d['metrics']['total_real_contact_area_mm2'], 'mm2'" &&
        echo "$body" | json_get "all(v > 0 for v in d['metrics'].values())" | grep -qx True
}

check_healthy() {
    local s t=$SECONDS
    while [ $((SECONDS - t)) -lt 90 ]; do
        s=$(docker inspect -f '{{.State.Health.Status}}' "$MAIN")
        [ "$s" = healthy ] && return 0
        sleep 1
    done
    echo "health status: $s" >&2
    docker inspect -f '{{json .State.Health.Log}}' "$MAIN" | tail -c 600 >&2
    return 1
}

check_non_root() { # every process of the container runs as uid 10001 and gid 10001
    local rows
    rows=$(docker top "$MAIN" -o pid,uid,gid,args | tail -n +2)
    echo "$rows" | awk '{ print $2, $3, $4, $5, $6, $7 }'
    [ -n "$rows" ] && ! echo "$rows" | awk '$2 != 10001 || $3 != 10001 { bad = 1 } END { exit !bad }'
}

check_tables_read_only() { # the service user can change no shipped table, ski or texture
    docker exec "$MAIN" python -c "
import os, sys
from skisnow.app.storage.common import tables_dir
d = tables_dir()
files = [os.path.join(r, f) for r, _, fs in os.walk(d) for f in fs]
dirs = [r for r, _, _ in os.walk(d)]
writable = [p for p in files + dirs if os.access(p, os.W_OK)]
print(d, len(files), 'files,', len(writable), 'writable')
sys.exit(1 if writable or len(files) < 5 else 0)"
}

GRIND=ci-grind
check_upload_survives_restart() {
    local answer job state sha sha2 t
    # a 64 x 64 height map [um] as CSV, made here (no numpy needed on the host)
    awk 'BEGIN { srand(7); for (i = 0; i < 64; i++) { s = ""; for (j = 0; j < 64; j++) {
        s = s (j ? "," : "") sprintf("%.4f", sin(0.31 * i) + 0.5 * cos(0.73 * j + 0.2 * i) + 0.3 * rand()) }
        print s } }' >"$TMP/grind.csv"
    answer=$(curl -fsS --max-time 60 -F file=@"$TMP/grind.csv" -F name="$GRIND" \
        -F pixel_size_um=1 -F height_unit=um -F shop_code=CI "$(url "$PORT" /v1/grinds)") || return 1
    job=$(echo "$answer" | json_get "d['job']") || return 1
    t=$SECONDS
    while [ $((SECONDS - t)) -lt 300 ]; do
        state=$(curl -fsS "$(url "$PORT" "/v1/jobs/$job")" | json_get "d['state']")
        [ "$state" = done ] || [ "$state" = failed ] && break
        sleep 1
    done
    echo "upload job $job: $state after $((SECONDS - t)) s"
    [ "$state" = done ] || return 1
    sha=$(curl -fsS "$(url "$PORT" "/v1/grinds/$GRIND")" | json_get "d['sha256'], d['usable']") || return 1
    t=$SECONDS
    docker restart "$MAIN" >/dev/null
    wait_ready "$PORT" "$MAIN" 180 || return 1
    echo "restarted and ready in $((SECONDS - t)) s"
    sha2=$(curl -fsS "$(url "$PORT" "/v1/grinds/$GRIND")" | json_get "d['sha256'], d['usable']") || return 1
    echo "before: $sha; after: $sha2"
    [ "$sha" = "$sha2" ] && [ "${sha2##* }" = True ] || return 1
    # and the item answers a contact request after the restart
    curl -fsS --max-time 60 -o /dev/null "$(url "$PORT" /v1/contact)" \
        -H 'content-type: application/json' \
        -d '{"ski": "ski-a", "grind": "'"$GRIND"'", "load_kg": 40, "load_position_mm": -160,
             "snow_modulus_mpa": 200, "porosity": 0.5, "ski_model": "rigid"}'
}

check_pinned() { # every package in the image at the version of scripts/docker-constraints.txt
    docker exec "$MAIN" /opt/venv/bin/python -m pip freeze --all 2>/dev/null \
        >"$TMP/image-freeze.txt" || return 1
    python3 - "$TMP/image-freeze.txt" scripts/docker-constraints.txt <<'PY'
import re, sys
def pins(path):
    out = {}
    for line in open(path):
        line = line.split("#")[0].strip()
        if "==" in line:
            name, version = line.split("==", 1)
            out[re.sub(r"[-_.]+", "-", name).lower()] = version.strip()
    return out
image, wanted = pins(sys.argv[1]), pins(sys.argv[2])
off = {n: (v, wanted.get(n)) for n, v in image.items() if n not in ("pip",) and wanted.get(n) != v}
print(f"{len(image)} packages in the image; not at the pinned version: {off or 'none'}")
sys.exit(1 if off else 0)
PY
}

check_macro() {
    docker exec "$MAIN" skisnow macro --ski ski-a --load-kg 40 --load-position-mm -160 \
        --snow-modulus-mpa 200 --ski-model rigid --json |
        json_get "'apparent area', d['apparent_contact_area_cm2'], 'cm2'"
}

check_micro() {
    docker exec "$MAIN" skisnow micro grind-1 --nominal-pressure-kpa 30 --snow-modulus-mpa 200 \
        --json | json_get "'real contact area fraction', d['real_contact_area_fraction']"
}

check_fresh_starts() { # FRESH containers at once, each on a new empty volume and its own port
    local i c port t0=$SECONDS bad=0 pids=()
    for i in $(seq "$FRESH"); do
        docker volume create --label "$LABEL" "$NAME-fresh-$i" >/dev/null
        docker run -d --name "$NAME-fresh-$i" --label "$LABEL" --network host \
            -e SKISNOW_PORT=$((FRESH_PORT0 + i)) -v "$NAME-fresh-$i:/srv/skisnow/data" \
            "$IMAGE" >/dev/null
    done
    log "$FRESH containers started"
    for i in $(seq "$FRESH"); do
        wait_ready $((FRESH_PORT0 + i)) "$NAME-fresh-$i" 240 &
        pids+=($!)
    done
    for i in "${!pids[@]}"; do wait "${pids[$i]}" || bad=1; done
    log "all answered /readyz after $((SECONDS - t0)) s"
    [ $((SECONDS - t0)) -lt 30 ] && sleep $((30 - (SECONDS - t0)))
    for i in $(seq "$FRESH"); do
        c=$NAME-fresh-$i
        state=$(docker inspect -f '{{.State.Status}} exit={{.State.ExitCode}} restarts={{.RestartCount}}' "$c")
        echo "$c after $((SECONDS - t0)) s: $state"
        [ "${state%% *}" = running ] || bad=1
    done
    # free the memory before anything else runs
    for i in $(seq "$FRESH"); do docker rm -f "$NAME-fresh-$i" >/dev/null; done
    return "$bad"
}

# ---------------------------------------------------------------- run
step "install docker.io, debootstrap if missing" install_tools
step "Docker daemon" start_daemon
step "base image $BASE" make_base
step "docker build" build_image
BUILT=1
log "image size: $(docker image inspect -f '{{.Size}}' "$IMAGE" | awk '{printf "%.0f MB", $1 / 1e6}')"
step "docker run (port $PORT, volume $NAME-data)" run_main
check "/readyz answers" check_ready
check "one /v1/contact answer" check_contact
check "health status turns healthy" check_healthy
check "runs as uid 10001 gid 10001" check_non_root
check "tables read-only for the service user" check_tables_read_only
check "uploaded grind survives docker restart" check_upload_survives_restart
check "dependencies at the versions of scripts/docker-constraints.txt" check_pinned
check "skisnow macro --ski ski-a in the container" check_macro
check "skisnow micro grind-1 in the container" check_micro
docker rm -f "$MAIN" >/dev/null
check "$FRESH fresh starts on empty volumes: ready, running after 30 s" check_fresh_starts
