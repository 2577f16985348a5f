#!/usr/bin/env bash
# Idempotent development environment for strapdown_ros (no system ROS needed).
#
# Creates .venv in the repository root and installs the package editable with the
# `ros`, `tools`, `test`, `bench`, `fast` and `fleet` extras (rclpy + messages come from PyPI). The install is
# skipped when nothing relevant changed since the last successful run: a stamp file in
# .venv holds a hash of the packaging metadata (setup.py, setup.cfg, package.xml,
# pyproject.toml if any), the extras and the interpreter version.
#
# Works from any cwd. Progress goes to stderr so wrappers keep a clean stdout.
# Env knobs: PYTHON=/path/to/python (interpreter to create the venv with),
#            SETUP_ENV_FORCE=1 (reinstall even if the stamp matches),
#            SETUP_ENV_VERBOSE=1 (show pip's full output).
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"

VENV="$ROOT/.venv"
VPY="$VENV/bin/python"
STAMP="$VENV/.strapdown_ros_setup.stamp"
EXTRAS="ros,tools,test,bench,fast,fleet"
MIN_PIP="21.3"   # first pip with PEP 660 editables (console scripts land in .venv/bin)

say() { printf '[setup_env] %s\n' "$*" >&2; }
die() { printf '[setup_env] ERROR: %s\n' "$*" >&2; exit 1; }

# --- pick the interpreter ---------------------------------------------------------------
pick_python() {
    if [[ -n "${PYTHON:-}" ]]; then
        command -v "$PYTHON" || die "PYTHON=$PYTHON not found"
    elif command -v python3.11 >/dev/null 2>&1; then
        command -v python3.11
    elif command -v python3 >/dev/null 2>&1; then
        command -v python3
    else
        die "no python3.11 or python3 on PATH; install Python >= 3.10"
    fi
}

py_ok() {  # $1 = interpreter; true if it runs and is >= 3.10
    "$1" -c 'import sys; sys.exit(0 if sys.version_info >= (3, 10) else 1)' >/dev/null 2>&1
}

# one setup at a time (e.g. demo.sh and test.sh started together)
mkdir -p "$VENV"
if command -v flock >/dev/null 2>&1; then
    exec 9>"$VENV/.setup.lock"
    flock 9
fi

# --- venv ----------------------------------------------------------------------------------
if [[ -x "$VPY" ]] && py_ok "$VPY"; then
    :
else
    BASE_PY="$(pick_python)"
    if ! py_ok "$BASE_PY"; then
        ver="$("$BASE_PY" -c 'import sys; print("%d.%d.%d" % sys.version_info[:3])' 2>/dev/null || echo '?')"
        die "$BASE_PY is Python $ver; strapdown_ros needs Python >= 3.10 (set PYTHON=/path/to/python3.x)"
    fi
    if [[ -e "$VPY" ]]; then
        say "existing .venv is unusable; recreating it"
        find "$VENV" -mindepth 1 -maxdepth 1 ! -name .setup.lock -exec rm -rf {} +
    fi
    say "creating .venv with $BASE_PY ($("$BASE_PY" -c 'import sys; print(sys.version.split()[0])'))"
    "$BASE_PY" -m venv "$VENV" \
        || die "'$BASE_PY -m venv' failed (on Debian/Ubuntu: apt-get install python3-venv)"
fi

# --- stamp -----------------------------------------------------------------------------------
hash_inputs() {
    {
        "$VPY" -c 'import sys; print(sys.version)'
        echo "extras=$EXTRAS"
        for f in setup.py setup.cfg package.xml pyproject.toml; do
            if [[ -f "$f" ]]; then echo "== $f"; cat "$f"; fi
        done
    } | "$VPY" -c 'import hashlib, sys; print(hashlib.sha256(sys.stdin.buffer.read()).hexdigest())'
}
WANT="$(hash_inputs)"

installed_ok() {
    [[ -f "$STAMP" && "$(cat "$STAMP")" == "$WANT" && -x "$VENV/bin/strapdown_demo" ]] || return 1
    # the editable install itself (its .pth / finder) must still be there
    "$VPY" -c 'import importlib.metadata as m; m.distribution("strapdown_ros")' >/dev/null 2>&1
}

if [[ "${SETUP_ENV_FORCE:-0}" != "1" ]] && installed_ok; then
    say ".venv up to date ($("$VPY" -c 'import sys; print(sys.version.split()[0])'))"
    exit 0
fi

# --- pip --------------------------------------------------------------------------------------
PIPQ=(-q)
[[ "${SETUP_ENV_VERBOSE:-0}" == "1" ]] && PIPQ=()
# pip with exit status kept; drops the per-package "Location 'file:///...' is ignored"
# warnings that local index mirrors produce for every package they don't carry
pip_() {
    { "$VPY" -m pip "$@" 2>&1 1>&3 3>&- | sed -u "/^WARNING: Location '.*' is ignored: it is neither a file nor a directory\.\$/d" >&2; } 3>&1
}

pip_ver="$("$VPY" -m pip --version 2>/dev/null | awk '{print $2}')" || pip_ver=""
if [[ -z "$pip_ver" ]]; then
    say "bootstrapping pip"
    "$VPY" -m ensurepip --upgrade >/dev/null || die "no pip in .venv and ensurepip failed"
    pip_ver="$("$VPY" -m pip --version | awk '{print $2}')"
fi
if ! "$VPY" - "$pip_ver" "$MIN_PIP" <<'EOF'
import re, sys
v = lambda s: tuple(int(x) for x in re.findall(r"\d+", s)[:3])
sys.exit(0 if v(sys.argv[1]) >= v(sys.argv[2]) else 1)
EOF
then
    say "upgrading pip $pip_ver (< $MIN_PIP)"
    pip_ install "${PIPQ[@]}" --upgrade pip
fi

# --- package ----------------------------------------------------------------------------------
say "pip install -e '.[$EXTRAS]' (first run downloads rclpy & friends; takes a while)"
t0=$SECONDS
pip_ install "${PIPQ[@]}" --progress-bar off -e ".[$EXTRAS]"
say "pip install done in $((SECONDS - t0)) s"

# Console scripts must be on .venv/bin. A legacy `setup.py develop` install would honour
# setup.cfg [develop] script_dir and put them in .venv/lib/strapdown_ros instead.
for exe in imu_sim_node sins_node strapdown_demo sins_bench coning_bench; do
    [[ -x "$VENV/bin/$exe" ]] || die ".venv/bin/$exe missing after install (legacy 'setup.py develop' editable? need pip >= $MIN_PIP and setuptools >= 64)"
done

# numba's on-disk cache (njit(cache=True), strapdown_ros/__pycache__): one tiny sins_bag run with
# navigation and the attitude filter's warm-up (its kernels and the live check's) compile every
# kernel the offline tools and the nodes use, so the first real run after an install loads them
# instead of compiling (~35 s and ~27 s).  Optional: a failure only means that
# the first run compiles; STRAPDOWN_SKIP_WARMUP=1 skips it.
warm_kernels() {
    local d rc=1
    d="$(mktemp -d)" || return 1
    if "$VENV/bin/record_sim" "$d/bag" --duration 2 -p profile:=coordinated_turn >/dev/null 2>&1 \
        && "$VENV/bin/python" -c "import sys, pathlib
from strapdown_ros.bench.sins_bag_bench import navigation_parameters
navigation_parameters('coordinated_turn', pathlib.Path(sys.argv[1]))" "$d/p.yaml" \
        && "$VENV/bin/sins_bag" "$d/bag" --params "$d/p.yaml" --output "$d/o.csv" --quiet \
            >/dev/null 2>&1 \
        && "$VENV/bin/python" -c "from strapdown_ros.params import model_and_settings
from strapdown_ros.estimation.filter_system import FilterSettings, warm_up
m, s = model_and_settings('attitude_filter_node', {})
warm_up(m, FilterSettings.from_values(s))" >/dev/null 2>&1; then
        rc=0
    fi
    rm -rf "$d"
    return $rc
}
if [[ "${STRAPDOWN_SKIP_WARMUP:-0}" != 1 ]] && "$VENV/bin/python" -c "import numba" 2>/dev/null; then
    t0=$SECONDS
    if warm_kernels; then
        say "numba kernel cache warm in $((SECONDS - t0)) s"
    else
        say "numba kernel warm-up skipped (the first sins_bag run compiles its kernels)"
    fi
fi

echo "$WANT" >"$STAMP"
say "ready: $VENV"
