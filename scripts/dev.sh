#!/usr/bin/env bash
# One entry point that sets everything up from nothing and then does one job.
#
#   bash scripts/dev.sh demo    set up, then render scenes/projectile.yaml into renders/
#   bash scripts/dev.sh test    set up, then run the whole test suite (what CI runs); --fast: the fast tier only
#                               (no test marked slow: whole-pipeline renders, long simulations), for the inner loop
#   bash scripts/dev.sh bench   set up, then run the benchmark suite and print its table
#   bash scripts/dev.sh gallery set up, then redraw docs/gallery.md: one still per bundled scene at final quality
#   bash scripts/dev.sh accuracy  set up, then regenerate docs/accuracy.md (studies of the bundled scenes)
#   bash scripts/dev.sh notebooks set up, then run docs/notebooks/*.ipynb and save them with their outputs
#   bash scripts/dev.sh fuzz    set up, then run 10 000 mutated scenes through validate and simulate (a table)
#   bash scripts/dev.sh setup   only set up
#
# Set-up is idempotent and quick when nothing changed: it installs the off-screen OpenGL library when it is
# missing (as root, with apt-get; otherwise it says what to install), creates .venv with Python >= 3.11 and
# installs the package in editable mode with its test dependencies, re-installing only when pyproject.toml changes.
# The test command also installs Chromium (for the report page's browser test) when it is missing.
set -euo pipefail

cd "$(dirname "${BASH_SOURCE[0]}")/.."
root=$(pwd)
venv="$root/.venv"

say() { printf '[animbatch setup] %s\n' "$*" >&2; }

find_python() {
    for candidate in "${PYTHON:-}" python3.13 python3.12 python3.11 python3; do
        [ -n "$candidate" ] || continue
        if command -v "$candidate" >/dev/null 2>&1 &&
            "$candidate" -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else 1)' 2>/dev/null; then
            command -v "$candidate"
            return 0
        fi
    done
    say "Python >= 3.11 is required and none was found (tried \$PYTHON, python3.13 … python3)."
    say "On Debian 12: apt-get install python3 python3-venv"
    exit 1
}

have_library() {
    local ldconfig
    ldconfig=$(command -v ldconfig || echo /sbin/ldconfig)
    "$ldconfig" -p 2>/dev/null | grep -q "$1"
}

try_apt_install() {
    # Install one Debian package (without recommends) as root with apt-get, refreshing the package lists only when
    # the first try fails. Returns 0 when installed, 1 when apt-get failed (said why), 2 when this user cannot.
    local package=$1 purpose=$2
    if [ "$(id -u)" != 0 ] || ! command -v apt-get >/dev/null 2>&1; then
        return 2
    fi
    say "installing $package ($purpose) with apt-get"
    export DEBIAN_FRONTEND=noninteractive
    if apt-get install -y --no-install-recommends "$package" >/dev/null 2>&1 ||
        { apt-get update -qq >/dev/null && apt-get install -y --no-install-recommends "$package" >/dev/null; }; then
        return 0
    fi
    say "apt-get could not install $package (no network or no package lists?)."
    say "Install it by hand: apt-get update && apt-get install $package"
    return 1
}

ensure_system_libraries() {
    # VTK draws off-screen through OSMesa or EGL; it loads either at run time (never an X server).
    if have_library 'libOSMesa.so.8'; then
        return 0
    fi
    local status=0
    try_apt_install libosmesa6 "off-screen OpenGL for rendering" || status=$?
    case $status in
        0) return 0 ;;
        1) exit 1 ;;
    esac
    if have_library 'libEGL.so.1' && have_library 'libEGL_mesa.so.0'; then
        say "libosmesa6 is not installed; using EGL (Mesa) instead."
        return 0
    fi
    say "No off-screen OpenGL library found, and this user cannot install one."
    say "Ask an administrator to run:  apt-get install libosmesa6"
    say "(Fedora/RHEL: dnf install mesa-libOSMesa)"
    exit 1
}

ensure_browser() {
    # The report page's test opens it in a real browser: Debian's Chromium, driven headless by Playwright. Without
    # it that test skips and says why; nothing else needs a browser.
    if command -v chromium >/dev/null 2>&1 || command -v chromium-browser >/dev/null 2>&1; then
        return 0
    fi
    local status=0
    try_apt_install chromium "the report page's browser test" || status=$?
    if [ "$status" = 2 ]; then
        say "chromium is not installed and this user cannot install it: the browser test will be skipped."
        say "Ask an administrator to run:  apt-get install chromium"
    fi
}

ensure_venv() {
    local python stamp
    if [ ! -x "$venv/bin/python" ]; then
        python=$(find_python)
        say "creating .venv with $python"
        "$python" -m venv "$venv" || {
            say "could not create a virtual environment; on Debian: apt-get install python3-venv"
            exit 1
        }
    fi
    stamp="$venv/.animbatch-installed-$(sha256sum pyproject.toml | cut -c1-16)"
    if [ ! -f "$stamp" ]; then
        say "installing animbatch and its dependencies into .venv (first run takes a minute)"
        "$venv/bin/python" -m pip install --quiet -e ".[test]"
        rm -f "$venv"/.animbatch-installed-*
        touch "$stamp"
    fi
}

compile_bytecode() {
    # pip compiles the dependencies' bytecode but not an editable install's, and this environment may forbid
    # writing it (PYTHONDONTWRITEBYTECODE): every process (test workers, the CLI, render and Dask workers) would then
    # compile animbatch's 200 modules from source, half a second each time. compileall writes it regardless, and
    # only for files that changed.
    "$venv/bin/python" -m compileall -q -j 0 src >/dev/null || say "could not write bytecode for src/ (slower start-up only)"
}

setup() {
    ensure_system_libraries
    ensure_venv
    compile_bytecode
}

build_kernels() {
    # The compiled kernels (numba), built once per machine and version into the user's cache (about four minutes
    # on 2 cores the first time, a second after): here, once, rather than in every test process at once.
    say "compiled kernels (the first time on a machine this compiles them: about four minutes):"
    if ! "$venv/bin/animbatch" doctor --kernels >&2; then
        say "some compiled kernels could not be built: numpy runs those parts (see 'animbatch doctor --kernels')."
    fi
}

command=${1:-}
shift || true
case "$command" in
    setup)
        setup
        ;;
    demo)
        setup
        exec "$venv/bin/animbatch" render scenes/projectile.yaml --out renders "$@"
        ;;
    test)
        setup
        ensure_browser
        build_kernels
        tier=()
        if [ "${1:-}" = "--fast" ]; then  # the inner loop: every test but those marked slow
            shift
            tier=(-m "not slow")
        fi
        # The suite starts a hundred Python processes (test workers, Dask workers, farm steps, CLI runs): with
        # bytecode caches off (PYTHONDONTWRITEBYTECODE, set on some machines) each one compiles the package again and
        # each test worker rewrites all 160 test modules' asserts again (some 5 s a worker).
        unset PYTHONDONTWRITEBYTECODE
        # Spread the tests over the machine's cores (at most 4: each render test holds a software OpenGL context);
        # tests marked xdist_group("dask") go to one test process, to share its Dask cluster.
        exec "$venv/bin/python" -m pytest -n auto --maxprocesses=4 --dist loadgroup "${tier[@]}" "$@"
        ;;
    bench)
        setup
        if ! "$venv/bin/python" -c "import mujoco" 2>/dev/null; then  # the peers' benchmark measures against it
            say "installing the benchmarks' peers (the bench extra: MuJoCo)"
            "$venv/bin/python" -m pip install --quiet -e ".[test,bench]" || say "MuJoCo could not be installed: the peers' benchmark will skip"
        fi
        build_kernels
        exec "$venv/bin/python" benchmarks/run.py "$@"
        ;;
    gallery)
        setup
        exec "$venv/bin/python" scripts/gallery.py "$@"
        ;;
    fuzz)
        setup
        exec "$venv/bin/python" benchmarks/fuzz.py "$@"
        ;;
    accuracy)
        setup
        exec "$venv/bin/python" -m animbatch.study.document "$@"
        ;;
    notebooks)
        setup
        exec "$venv/bin/python" scripts/notebooks.py "$@"
        ;;
    *)
        echo "usage: bash scripts/dev.sh {demo|test|bench|gallery|fuzz|accuracy|notebooks|setup} [extra arguments]" >&2
        exit 2
        ;;
esac
