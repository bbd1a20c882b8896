#!/usr/bin/env bash
# Soak tests of the daemon: installs the dependencies, builds the release preset and runs the
# tests labelled `soak` (excluded from `ctest --preset release`, whose label exclusion would
# also drop them if combined with `-L soak`; hence the dedicated `soak` test preset).
#
# Usage: tools/run_soak.sh [SECONDS]         the full-speed and 30 Hz phases (Soak.*)
#        tools/run_soak.sh hour [SECONDS]    the hour at 30 Hz with SIGHUP reloads (SoakHour.*)
#        tools/run_soak.sh all               both (`ctest --preset soak`)
#   SECONDS  Soak.*: length of the full-speed phase (default: $CLUTTERSEG_SOAK_SECONDS, else
#            1800); the 30 Hz phase lasts a sixth of it, at least 30 s
#            ($CLUTTERSEG_SOAK_30HZ_SECONDS). SoakHour.*: length of the run (default
#            $CLUTTERSEG_SOAK_HOUR_SECONDS, else 3600); reloads every
#            $CLUTTERSEG_SOAK_RELOAD_SECONDS (10), samples every
#            $CLUTTERSEG_SOAK_HOUR_SAMPLE_SECONDS (60), warm-up $CLUTTERSEG_SOAK_WARMUP_SECONDS
#            (300, at most a quarter of the run).
# Samples (phase, time, VmRSS, descriptors, threads) go to build/release/soak_samples.csv; the
# summaries are printed. Everything is generated (clutterseg-synth, src/synth): no data needed.
# See docs/reliability.md.
set -euo pipefail
cd "$(dirname "$0")/.."
what="phases"
case "${1:-}" in
  hour | all)
    what="$1"
    shift
    ;;
  -h | --help)
    sed -n '2,18p' "$0" | sed 's/^# \{0,1\}//'
    exit 0
    ;;
esac
if [ $# -ge 1 ]; then
  if [ "${what}" = "hour" ]; then
    export CLUTTERSEG_SOAK_HOUR_SECONDS="$1"
  else
    export CLUTTERSEG_SOAK_SECONDS="$1"
  fi
fi
bash tools/install_deps.sh
cmake --preset release
cmake --build --preset release -j "$(nproc)" --target soak_test
# The ctest timeout of each soak test is CLUTTERSEG_SOAK_TIMEOUT_S (CMake cache, 7200 s).
case "${what}" in
  phases)
    echo "soak: ${CLUTTERSEG_SOAK_SECONDS:-1800} s at full speed, then the 30 Hz phase"
    ctest --preset soak -R '^Soak\.'
    ;;
  hour)
    echo "soak: ${CLUTTERSEG_SOAK_HOUR_SECONDS:-3600} s at 30 Hz, SIGHUP every ${CLUTTERSEG_SOAK_RELOAD_SECONDS:-10} s"
    ctest --preset soak -R '^SoakHour\.'
    ;;
  all) ctest --preset soak ;;
esac
echo "samples: build/release/soak_samples.csv"
