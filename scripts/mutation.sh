#!/usr/bin/env bash
# Mutation testing of geometry/kernels.py, the numerical solver's PCA initialisation, evaluation/metrics.py,
# fitting/scoring.py and fitting/backend.py (see scripts/mutation.py and docs/mutation.md). Not part of CI:
# a few minutes on two cores, at low priority. Arguments go to scripts/mutation.py (e.g. --only kernels, --list).
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON="${PYTHON:-python}"
exec nice -n 10 "$PYTHON" scripts/mutation.py "$@"
