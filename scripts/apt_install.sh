#!/usr/bin/env bash
# Install Debian packages the test and docs commands need, when they are missing:
#
#   bash scripts/apt_install.sh WHO WHAT PACKAGE...
#
# WHO names the calling script in messages, WHAT says what skips without the packages. Uses
# apt-get as root, or through passwordless sudo; without either (or without apt-get) it says so
# and returns 0: the tests that need the packages then skip, or fail under CI=true. Set
# CHIPTWIN_NO_APT=1 to skip this step.
set -euo pipefail
who="$1" what="$2"
shift 2
[ "$#" -gt 0 ] && [ "${CHIPTWIN_NO_APT:-0}" != "1" ] || exit 0

as_root=()
if [ "$(id -u)" != "0" ]; then
    if command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
        as_root=(sudo -n)
    else
        as_root=(none)
    fi
fi
if [ "${as_root[*]-}" = "none" ] || ! command -v apt-get >/dev/null 2>&1; then
    echo "$who: cannot install $* (no apt-get, or not root and no sudo);" \
         "$what will skip (or fail with CI=true)" >&2
    exit 0
fi
echo "$who: installing $* with apt-get" >&2
export DEBIAN_FRONTEND=noninteractive
if ! { "${as_root[@]}" apt-get update -qq >/dev/null &&
       "${as_root[@]}" apt-get install -y -qq --no-install-recommends "$@" >/dev/null; }; then
    echo "$who: apt-get could not install $*" >&2
fi
