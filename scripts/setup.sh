#!/usr/bin/env bash
# Install everything flowmc needs on a fresh Debian machine (run as root or with sudo).
#   bash scripts/setup.sh          the editor and runtime: pip install -e .
#   bash scripts/setup.sh --test   also what the tests use: LinuxCNC (rs274 + simulator), Chromium, pytest, playwright
set -euo pipefail
cd "$(dirname "$0")/.."
want_test=0
[[ "${1:-}" == "--test" ]] && want_test=1
SUDO=""
[[ $(id -u) -ne 0 ]] && SUDO="sudo"
if [[ $want_test -eq 1 ]]; then
  need=()
  command -v rs274 >/dev/null 2>&1 || need+=(linuxcnc-uspace)
  command -v chromium >/dev/null 2>&1 || need+=(chromium)
  if [[ ${#need[@]} -gt 0 ]]; then
    export DEBIAN_FRONTEND=noninteractive
    $SUDO apt-get update -q
    $SUDO apt-get install -y -q --no-install-recommends "${need[@]}"
  fi
  python3 -m pip install -q -e '.[test]'
else
  python3 -m pip install -q -e .
fi
