#!/usr/bin/env bash
# Measures the daemon end to end on .oni recordings: replay throughput at --speed max (frames
# looped until N are published), capture-to-publish latency when fed at the recorded 30 Hz
# (RT_FRAMES frames, looped), frames dropped, and peak RSS. Latency percentiles are over the
# frames after the first WARMUP (default 30, one second: work buffers still growing and the
# backlog of the slow first frames). FPS counts every published frame over the whole run,
# start-up included. Prints one Markdown table row per recording and mode.
# A looped recording restarts one frame early in OniFile (two frames in flight once per
# pass): give the 30 Hz run a recording longer than WARMUP + RT_FRAMES to measure a camera's
# steady state.
# Usage: tools/bench/daemon_bench.sh [BUILD_DIR] [FRAMES] RECORDING.oni...
#   BUILD_DIR defaults to build/release, FRAMES (published at speed max) to 600.
#   DAEMON_ARGS adds options to every daemon run (e.g. "--set processing.prefault_heap_mb=0").
#   OVERLAYS=1 adds a third run per recording: 30 Hz with overlay PNGs written (--png-dir), to
#   compare its latency with the plain 30 Hz run; its "dropped" column then also gives the
#   overlays written and dropped.
# Make recordings with: clutterseg-synth --oni out.oni --count 360 --seed 101
#                       clutterseg-record --from-pcd ../shared/data/mosd-learn --fps 30 out.oni
set -euo pipefail
cd "$(dirname "$0")/../.."
build=${1:-build/release}
frames=${2:-600}
rt_frames=${RT_FRAMES:-300}  # frames published at the recorded 30 Hz
warmup=${WARMUP:-30}         # first frames left out of the percentiles (start-up: buffers growing, first backlog)
shift 2 || true
daemon=$build/src/daemon/clutterseg
listen=$build/tools/clutterseg-listen
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

echo "| recording | mode | frames | FPS | segment p50 / p99 ms | capture-to-publish p50 / p99 ms | dropped | peak RSS MiB |"
echo "|---|---|---|---|---|---|---|---|"
for oni in "$@"; do
  name=$(basename "$oni")
  modes=(max realtime)
  [ "${OVERLAYS:-0}" = 1 ] && modes+=(overlays)
  for mode in "${modes[@]}"; do
    log=$tmp/$mode.lcmlog
    if [ "$mode" = max ]; then
      args=(--speed max --loop --max-frames "$frames")
    elif [ "$mode" = realtime ]; then
      args=(--speed realtime --loop --max-frames "$rt_frames")
    else
      rm -rf "$tmp/png" && mkdir -p "$tmp/png"
      args=(--speed realtime --loop --max-frames "$rt_frames" --png-dir "$tmp/png")
    fi
    start=$(date +%s.%N)
    # shellcheck disable=SC2086  # DAEMON_ARGS is a list of words
    /usr/bin/time -f "%M" -o "$tmp/rss" "$daemon" --source "$oni" "${args[@]}" \
      --lcm-url "file://$log?mode=w" --log-level warn ${DAEMON_ARGS:-} > /dev/null 2>&1
    end=$(date +%s.%N)
    "$listen" --lcm-url "file://$log?speed=0" > "$tmp/listen.txt" 2>&1 || true
    pngs=$( (find "$tmp/png" -name '*.png' 2> /dev/null || true) | wc -l)
    python3 - "$name" "$mode" "$start" "$end" "$(tail -1 "$tmp/rss")" "$pngs" \
      "$(python3 tools/bench/listen_latency.py "$tmp/listen.txt" --warmup "$warmup" --json)" <<'PY'
import json, sys
name, mode, start, end, rss_kb, pngs, r = sys.argv[1:]
r = json.loads(r)
dropped = "?" if r["dropped"] is None else str(r["dropped"])
if mode == "overlays" and r["overlays_written"] is not None:
    dropped += "; overlays %d written, %d dropped, %s PNGs" % (
        r["overlays_written"], r["overlays_dropped"], pngs)
n = r["published"]
print("| %s | %s | %d | %.1f | %.1f / %.1f | %.1f / %.1f | %s | %.0f |" % (
    name, {"max": "speed max", "realtime": "30 Hz", "overlays": "30 Hz + PNGs"}[mode], n,
    n / (float(end) - float(start)), r["seg_p50"], r["seg_p99"], r["c2p_p50"], r["c2p_p99"],
    dropped, int(rss_kb) / 1024))
PY
  done
done
