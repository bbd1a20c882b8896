#!/usr/bin/env bash
# Soak test of the daemon: installs the dependencies, builds the release preset and runs the
# tests labelled `soak` (excluded from `ctest --preset release`, whose label exclusion would
# also drop them if combined with `-L soak`; hence the dedicated `soak` test preset).
#
# Usage: tools/run_soak.sh [SECONDS]
#   SECONDS  length of the full-speed phase (default: $CLUTTERSEG_SOAK_SECONDS, else 1800);
#            the 30 Hz phase lasts a sixth of it, at least 30 s ($CLUTTERSEG_SOAK_30HZ_SECONDS).
# Samples (VmRSS, descriptors, threads every 5 s) go to build/release/soak_samples.csv; the
# summary is printed. Needs the shared data (mosd-learn) beside the checkout. See
# docs/reliability.md.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ $# -ge 1 ]; then export CLUTTERSEG_SOAK_SECONDS="$1"; fi
bash tools/install_deps.sh
cmake --preset release
cmake --build --preset release -j "$(nproc)" --target soak_test
echo "soak: ${CLUTTERSEG_SOAK_SECONDS:-1800} s at full speed, then the 30 Hz phase"
# The ctest timeout of each soak test is CLUTTERSEG_SOAK_TIMEOUT_S (CMake cache, 7200 s).
ctest --preset soak
echo "samples: build/release/soak_samples.csv"
