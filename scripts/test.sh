#!/usr/bin/env bash
# The project's one test command, for a fresh Debian machine with Python 3.11 (and CI):
#
#   bash scripts/test.sh [--all] [pytest arguments]
#
# By default the quick tier: every test but the slow tier (tests/conftest.py SLOW, marked
# `slow`: whole runs, processes, co-simulation, million-draw statistics), under 2 minutes on 2
# cores. `--all` runs every test, the slow tier too, in one session: what CI runs (.ci/run);
# `-m slow` runs the slow tier alone. A `-m` of your own replaces the default `-m "not slow"`.
#
# 1. Installs what the RTL co-simulation needs when it is missing, with apt-get (as root, or
#    through passwordless sudo): verilator, iverilog, ccache, g++, make. Tested with Debian 12's
#    packages: Verilator 5.006 and Icarus Verilog 11.0 (rtl_ref refuses Verilator < 5.0 and
#    Icarus < 11.0). Set CHIPTWIN_NO_APT=1 to skip this step.
# 2. The test extra, installed the way chiptwin is (scripts/pip_install.sh): after a
#    `pip install .` it stays an installed package (`pip install ".[test]"`, refreshed from this
#    checkout), else `pip install -e ".[test]"`.
# 3. python -m pytest -n auto --dist loadgroup --durations=15 [-m "not slow"] "$@"
#    (pytest-xdist: one worker per core; the modules of tests/conftest.py's XDIST_GROUPS share
#    costly fixtures and each group runs on one worker, every other test goes where a worker is
#    free; the slowest 15 tests listed at the end, and any test outside the slow tier that took
#    1.5 s or more; pass -n 0 to run in one process, e.g. with --pdb). The groups need
#    pytest < 9.2 (the test extra pins it: pytest-dev/pytest-xdist#1386); before that pin they
#    silently did nothing.
#
# Without the simulators (and no way to install them) the RTL tests skip with a message saying
# how to install them; with CI=true they fail instead.
set -euo pipefail
cd "$(dirname "$0")/.."
export PIP_DISABLE_PIP_VERSION_CHECK=1
# Let Python cache compiled modules in __pycache__ (git ignores it). Some machine images set
# PYTHONDONTWRITEBYTECODE (this project's does): then every xdist worker and every subprocess a
# test starts compiles chiptwin's and the tests' sources again, and pytest rewrites every test
# module's asserts again. Measured: collection 6.8 s a worker without the cache, 3.7 s with it.
unset PYTHONDONTWRITEBYTECODE

PY="${PYTHON:-}"
if [ -z "$PY" ]; then
    if command -v python >/dev/null 2>&1; then PY=python; else PY=python3; fi
fi

missing=()
command -v verilator >/dev/null 2>&1 || missing+=(verilator)
{ command -v iverilog && command -v vvp; } >/dev/null 2>&1 || missing+=(iverilog)
command -v ccache >/dev/null 2>&1 || missing+=(ccache)
command -v g++ >/dev/null 2>&1 || missing+=(g++)
command -v make >/dev/null 2>&1 || missing+=(make)

bash scripts/apt_install.sh test.sh "the RTL tests" "${missing[@]}"

if command -v verilator >/dev/null 2>&1; then
    echo "test.sh: $(verilator --version | head -n 1)  (tested: 5.006)" >&2
fi
if command -v iverilog >/dev/null 2>&1; then
    echo "test.sh: $(iverilog -V 2>&1 | head -n 1)  (tested: 11.0)" >&2
fi

bash scripts/pip_install.sh "$PY" test

tier=(-m "not slow")  # the quick tier, unless --all or a -m of the caller's
args=()
for a in "$@"; do
    case "$a" in
        --all) tier=() ;;
        -m|-m*) tier=(); args+=("$a") ;;
        *) args+=("$a") ;;
    esac
done
exec "$PY" -m pytest -n auto --dist loadgroup --durations=15 "${tier[@]}" "${args[@]}"
