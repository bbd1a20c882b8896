#!/usr/bin/env bash
# Several cameras on one host: runs one daemon per recording AT THE SAME TIME, each replaying
# its recording at the recorded 30 Hz (looped) under its own camera_name into its own file://
# log, as clutterseg@NAME.service instances would run side by side, and reports per camera:
# frames published, frame_seq gaps (source frames never published), frames dropped (status),
# and segment and capture-to-publish percentiles over the frames after the first WARMUP.
# A run meets the bar when every camera has 0 gaps, 0 dropped and p99 <= the 33 ms period.
# Usage: tools/bench/multi_camera_bench.sh [BUILD_DIR] [FRAMES] RECORDING.oni...
#   BUILD_DIR defaults to build/release, FRAMES (published per camera) to 600.
#   DAEMON_ARGS adds options to every daemon; the template unit clutterseg@.service runs each with
#   "--threads 1 --set processing.realtime_priority=10 --set camera.decimation=2".
#   WARMUP (default 30) frames per camera are left out of the percentiles.
#   STAGGER_MS (default 0) waits this long between two daemons' starts: free-running cameras
#   deliver their frames at unrelated phases, daemons started together replay theirs at
#   nearly the same instants (the worst case: every frame meets the others' frames).
# Make recordings with: clutterseg-synth --oni out.oni --count 360 --seed 606
set -euo pipefail
cd "$(dirname "$0")/../.."
build=${1:-build/release}
frames=${2:-600}
warmup=${WARMUP:-30}
shift 2 || true
[ $# -ge 1 ] || { echo "usage: $0 [BUILD_DIR] [FRAMES] RECORDING.oni..." >&2; exit 2; }
daemon=$build/src/daemon/clutterseg
listen=$build/tools/clutterseg-listen
tmp=$(mktemp -d)
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2> /dev/null || true; done
  rm -rf "$tmp"
}
trap cleanup EXIT

i=0
for oni in "$@"; do
  i=$((i + 1))
  # shellcheck disable=SC2086  # DAEMON_ARGS is a list of words
  "$daemon" --source "$oni" --speed realtime --loop --max-frames "$frames" \
    --set camera_name="cam$i" --lcm-url "file://$tmp/cam$i.lcmlog?mode=w" --log-level warn \
    ${DAEMON_ARGS:-} > "$tmp/cam$i.out" 2>&1 &
  pids+=($!)
  [ "${STAGGER_MS:-0}" = 0 ] || sleep "$(awk -v ms="$STAGGER_MS" 'BEGIN { printf "%.3f", ms / 1000 }')"
done
rc=0
for p in "${pids[@]}"; do wait "$p" || rc=$?; done
pids=()
[ "$rc" = 0 ] || { echo "a daemon exited $rc:" >&2; cat "$tmp"/cam*.out >&2; exit 1; }

echo "| camera | recording | published | gaps | dropped | segment p50 / p99 ms | capture-to-publish p50 / p99 / max ms |"
echo "|---|---|---|---|---|---|---|"
i=0
for oni in "$@"; do
  i=$((i + 1))
  "$listen" --lcm-url "file://$tmp/cam$i.lcmlog?speed=0" > "$tmp/cam$i.txt" 2>&1 || true
  python3 - "cam$i" "$(basename "$oni")" \
    "$(python3 tools/bench/listen_latency.py "$tmp/cam$i.txt" --warmup "$warmup" --json)" <<'PY'
import json, sys
cam, name, r = sys.argv[1:]
r = json.loads(r)
print("| %s | %s | %d | %d | %s | %.1f / %.1f | %.1f / %.1f / %.1f |" % (
    cam, name, r["published"], r["gaps"], "?" if r["dropped"] is None else r["dropped"],
    r["seg_p50"], r["seg_p99"], r["c2p_p50"], r["c2p_p99"], r["c2p_max"]))
PY
done
