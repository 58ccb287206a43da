#!/usr/bin/env bash
# Install chiptwin with one of its extras, the way it is installed already:
#
#   bash scripts/pip_install.sh PYTHON EXTRA
#
# * installed from this folder with `pip install .` (a regular, non-editable install): the same
#   again, `pip install ".[EXTRA]"` — it stays an installed package (refreshed from this
#   checkout), never silently turned into an editable one;
# * an editable install, or none: `pip install -e ".[EXTRA]"` (a developer's checkout).
#
# Run from the repository's root. How it is installed is read from the distribution's
# direct_url.json (PEP 610), by an interpreter started with -I so that the checkout's own
# chiptwin.egg-info, beside pyproject.toml, is not what it finds.
set -euo pipefail
py="$1" extra="$2"
how="$("$py" -I - <<'PY'
import importlib.metadata as md, json
try:
    text = md.distribution("chiptwin").read_text("direct_url.json") or "{}"
except md.PackageNotFoundError:
    text = '{"dir_info": {"editable": true}}'  # none yet: a checkout's first run
print("editable" if json.loads(text).get("dir_info", {}).get("editable") else "installed")
PY
)"
if [ "$how" = "installed" ]; then
    echo "pip_install.sh: chiptwin is installed (not editable): pip install \".[$extra]\"" >&2
    "$py" -m pip install -q ".[$extra]"
else
    "$py" -m pip install -q -e ".[$extra]"
fi
