#!/usr/bin/env bash
# Sets up a fresh Debian 12 machine, builds clutterseg (release, warnings as errors) and runs
# the default test suite. Long soak and fuzz runs are excluded: see docs/reliability.md.
# Tests labelled `realdata` need the real data sets (tools/fetch_data.sh; docs/testing.md):
# without them they skip, and the last line says so; with them, a skipped `realdata` test is
# a failure.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/install_deps.sh
cmake --preset release
cmake --build --preset release -j "$(nproc)"

log=build/release/ctest-last.log
rc=0
ctest --preset release -j "$(nproc)" 2>&1 | tee "$log" || rc=$?

# The realdata tests that did not run, out of those the preset selects.
ctest --preset release -N -L realdata | sed -n 's/^ *Test *#[0-9]*: //p' | sed 's/ *#.*$//' | sort \
  > build/release/realdata-tests.txt
total=$(wc -l < build/release/realdata-tests.txt)
sed -n 's/^[[:space:]]*[0-9]* - \(.*\) (Skipped)$/\1/p' "$log" | sed 's/ *#.*$//' | sort |
  comm -12 - build/release/realdata-tests.txt > build/release/realdata-skipped.txt
skipped=$(wc -l < build/release/realdata-skipped.txt)
if root=$(tools/data_root.sh); then
  if [ "$skipped" -gt 0 ]; then
    echo "realdata: $skipped of $total tests skipped although the data is at $root:" >&2
    sed 's/^/  /' build/release/realdata-skipped.txt >&2
    rc=1
  fi
  echo "realdata: $((total - skipped)) of $total tests ran on the real data in $root"
else
  echo "realdata: 0 of $total tests ran (no real data found); run tools/fetch_data.sh" \
    "(or set CLUTTERSEG_DATA) to run them"
fi
exit "$rc"
