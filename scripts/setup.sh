#!/usr/bin/env bash
# Installs everything cuboids needs into .venv (or $VENV): the system library open3d needs, then the
# package with its pinned CPU torch. Safe to run again.
set -euo pipefail
VENV="${VENV:-.venv}"
PYTHON="${PYTHON:-python3}"

if ! ldconfig -p 2>/dev/null | grep -q "libusb-1.0.so.0"; then
  if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null; then
    echo "installing libusb-1.0 (needed by open3d)"
    apt-get update -qq && apt-get install -y -qq libusb-1.0-0 >/dev/null
  else
    echo "warning: libusb-1.0 is missing; open3d features (synthetic scenes) need it: apt-get install libusb-1.0-0" >&2
  fi
fi

if [ ! -x "$VENV/bin/python" ]; then
  "$PYTHON" -m venv "$VENV"
fi
# torch first, pinned: an unpinned torch would pull the CUDA build (several GB).
"$VENV/bin/pip" install -q "torch==2.13.0"
"$VENV/bin/pip" install -q -e ".[dev]"
touch "$VENV/.installed"
