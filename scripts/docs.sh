#!/usr/bin/env bash
# Build the documentation into docs/_build/html, warnings as errors:
#
#   bash scripts/docs.sh [extra sphinx-build arguments]
#
# 1. The docs extra (Sphinx, myst-nb, furo, ipykernel, Playwright, pytest), installed the way
#    chiptwin is: `pip install ".[docs]"` after a `pip install .`, else `pip install -e ".[docs]"`
#    (scripts/pip_install.sh)
# 2. sphinx-build -E -W --keep-going (every page read again: an incremental build re-runs only
#    the pages whose source changed, so a tutorial kept the output of the package it last ran;
#    not nitpicky: the docstrings' own cross-references are not yet
#    clean): a broken link or reference in the pages, a docstring Sphinx cannot read or a
#    tutorial cell that raises fails the build (every warning is listed first). The tutorials
#    and the outputs page run at every build; the CLI, scenario and study references are
#    generated from the code (docs/_ext/chiptwin_reference.py).
# 3. The site as a reader's browser shows it: tests/docs/test_site.py opens every page in headless
#    Chromium (Playwright, with Debian's chromium: installed here with apt-get when missing, as
#    root or through passwordless sudo, as scripts/test.sh installs the RTL simulators; set
#    CHIPTWIN_NO_APT=1 to skip) and fails on a console error, a broken image or local link, or a
#    tutorial or gallery page without a figure. Without Chromium it skips, and fails under
#    CI=true (.ci/run sets it).
#
# Everything the build writes to a temporary folder (the gallery's runs, each tutorial's
# mkdtemp, the notebook kernels' files: 8.7 MB a build) goes to one private TMPDIR, removed when
# this script exits, on success, failure or Ctrl-C.
set -euo pipefail
cd "$(dirname "$0")/.."
export PIP_DISABLE_PIP_VERSION_CHECK=1
export MPLBACKEND=Agg
docs_tmp="$(mktemp -d "${TMPDIR:-/tmp}/chiptwin-docs-build.XXXXXX")"
trap 'rm -rf "$docs_tmp"' EXIT
trap 'exit 130' INT
trap 'exit 143' TERM
export TMPDIR="$docs_tmp"
PY="${PYTHON:-}"
if [ -z "$PY" ]; then
    if command -v python >/dev/null 2>&1; then PY=python; else PY=python3; fi
fi

if ! command -v chromium >/dev/null 2>&1 && ! command -v chromium-browser >/dev/null 2>&1; then
    bash scripts/apt_install.sh docs.sh "the browser check" chromium
fi

bash scripts/pip_install.sh "$PY" docs
start=$(date +%s)
"$PY" -m sphinx -b html -E -W --keep-going -q docs docs/_build/html "$@"
echo "docs.sh: built docs/_build/html/index.html in $(( $(date +%s) - start )) s" >&2
start=$(date +%s)
CHIPTWIN_DOCS_BUILT=1 "$PY" -m pytest tests/docs -q -p no:cacheprovider
echo "docs.sh: every page checked in Chromium in $(( $(date +%s) - start )) s" >&2
