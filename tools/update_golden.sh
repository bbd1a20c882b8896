#!/usr/bin/env bash
# Regenerates the golden daemon log tests/daemon/golden/synth_seed11.lcmlog that the
# DaemonGolden test (daemon_e2e_test) compares fresh runs against.
#
# Usage: tools/update_golden.sh [BUILD_DIR]     (default BUILD_DIR: build/release)
#
# Run it only when an intended algorithm change alters the segmentation, and commit the new
# log together with that change. The recording and daemon command lines below must stay the
# same as in tests/daemon/e2e_ground_truth_test.cc.
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="$(cd "${1:-$repo/build/release}" 2>/dev/null && pwd)" || {
  echo "update_golden.sh: build directory '${1:-$repo/build/release}' not found" >&2
  exit 2
}
synth="$build/tools/clutterseg-synth"
daemon="$build/src/daemon/clutterseg"
regress="$build/tools/clutterseg-regress"
for exe in "$synth" "$daemon" "$regress"; do
  if [[ ! -x "$exe" ]]; then
    echo "update_golden.sh: $exe is missing; build it first:" >&2
    echo "  cmake --build $build -j2 --target clutterseg clutterseg-synth clutterseg_regress" >&2
    exit 2
  fi
done

golden="$repo/tests/daemon/golden/synth_seed11.lcmlog"
max_bytes=300000
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT

"$synth" --sequence --count 1 --frames 8 --seed 11 --oni "$tmp/synth_seed11.oni"
"$daemon" --source "$tmp/synth_seed11.oni" --speed max \
  --lcm-url "file://$tmp/new.lcmlog?mode=w" --log-level warn

# The same run twice must agree, or the golden log would not be reproducible.
"$daemon" --source "$tmp/synth_seed11.oni" --speed max \
  --lcm-url "file://$tmp/again.lcmlog?mode=w" --log-level warn
if ! "$regress" "$tmp/new.lcmlog" "$tmp/again.lcmlog" >"$tmp/repeat.txt"; then
  cat "$tmp/repeat.txt" >&2
  echo "update_golden.sh: two runs of the same recording differ; not updating" >&2
  exit 1
fi

size="$(stat -c %s "$tmp/new.lcmlog")"
if ((size > max_bytes)); then
  echo "update_golden.sh: new log is $size bytes (limit $max_bytes); is" \
    "lcm.label_compression zlib?" >&2
  exit 1
fi

if [[ -f "$golden" ]]; then
  echo "Changes against the current golden log:"
  "$regress" "$golden" "$tmp/new.lcmlog" || true
fi
cp "$tmp/new.lcmlog" "$golden"
echo "update_golden.sh: wrote $golden ($size bytes)"
