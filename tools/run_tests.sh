#!/usr/bin/env bash
# Sets up a fresh Debian 12 machine, builds clutterseg (release, warnings as errors) and runs
# the default test suite. Long soak and fuzz runs are excluded: see docs/reliability.md.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/install_deps.sh
cmake --preset release
cmake --build --preset release -j "$(nproc)"
ctest --preset release -j "$(nproc)"
