#!/usr/bin/env bash
# Set up studio on a fresh Debian/Ubuntu machine: system packages, a virtual environment in .venv,
# the package itself (editable) and, with --dev, everything the tests need.
#
#   bash tools/setup.sh          # runtime: studio + its libraries
#   bash tools/setup.sh --dev    # + test/lint tools, headless viewer (Mesa Vulkan) and Chromium for browser tests
#
# Safe to run again: every step skips what is already there.
set -euo pipefail
cd "$(dirname "$0")/.."

dev=0
for arg in "$@"; do
  case "$arg" in
    --dev) dev=1 ;;
    *) echo "setup.sh: unknown option '$arg' (use --dev)" >&2; exit 2 ;;
  esac
done

PY=${PYTHON:-python3}
if ! "$PY" -c 'import sys; sys.exit(sys.version_info < (3, 11))' 2>/dev/null; then
  echo "setup.sh: studio needs Python >= 3.11 (set PYTHON=/path/to/python3.11)" >&2
  exit 2
fi

apt_pkgs=()
if [ "$dev" = 1 ]; then
  # mesa-vulkan-drivers: software Vulkan for the headless Rerun viewer; chromium: annotation page tests
  apt_pkgs+=(mesa-vulkan-drivers chromium)
fi
missing=()
for p in "${apt_pkgs[@]}"; do
  dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if [ "${#missing[@]}" -gt 0 ]; then
  SUDO=""
  [ "$(id -u)" = 0 ] || SUDO="sudo"
  echo "setup.sh: installing system packages: ${missing[*]}"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

if [ ! -x .venv/bin/python ]; then
  "$PY" -m venv .venv
fi
# pip's own output (build warnings, index notes) goes to a log that is shown only when a step fails
log=.venv/setup-pip.log
: >"$log"
pip_install() {
  if ! .venv/bin/python -m pip install -q --disable-pip-version-check "$@" >>"$log" 2>&1; then
    echo "setup.sh: 'pip install $*' failed; its output:" >&2
    tail -n 40 "$log" >&2
    exit 1
  fi
}
pip=(pip_install)
echo "setup.sh: installing Python packages into .venv (a few minutes the first time; log: $log)"
"${pip[@]}" --upgrade pip
# torch first, pinned: an open range would pull a multi-GB CUDA build.
.venv/bin/python -c 'import torch' 2>/dev/null || "${pip[@]}" torch==2.13.0
if [ "$dev" = 1 ]; then
  "${pip[@]}" -e '.[dev]'
  # reference implementations the evaluator is cross-checked against; --no-deps because trackeval
  # declares the full opencv-python, which would replace the headless build
  .venv/bin/python -c 'import trackeval, pycocotools' 2>/dev/null \
    || "${pip[@]}" --no-deps trackeval==1.3.0 pycocotools
else
  "${pip[@]}" -e .
fi
echo "setup.sh: ready (.venv/bin/studio)"
