#!/usr/bin/env bash
# Sets up a fresh Debian 12 machine, builds clutterseg and runs the daemon: on an Asus Xtion /
# PrimeSense camera when one is plugged in, otherwise on a synthetic tabletop recording
# (.oni) generated here. Results: the live status line on the terminal, overlay PNGs and an
# LCM log under out/demo/, then a summary of the published objects.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/install_deps.sh
cmake --preset release
cmake --build --preset release -j "$(nproc)" --target clutterseg clutterseg-synth clutterseg-listen

bin=build/release
out=$PWD/out/demo
rm -rf "$out"
mkdir -p "$out/overlays"

# PrimeSense / Asus USB vendor ids.
camera=0
for v in /sys/bus/usb/devices/*/idVendor; do
  case "$(cat "$v" 2>/dev/null)" in 1d27|2bc5) camera=1 ;; esac
done

if [ "$camera" = 1 ] && [ "${CLUTTERSEG_DEMO_SYNTHETIC:-0}" != 1 ]; then
  echo "== camera found: segmenting live frames for 20 s (Ctrl-C stops) =="
  source=device
  extra=(--max-frames 600)
else
  echo "== no camera: generating a synthetic tabletop recording =="
  "$bin/tools/clutterseg-synth" --out "$out/recording" --oni "$out/recording.oni" \
    --sequence --count 2 --frames 8 --seed 1
  source=$out/recording.oni
  extra=(--speed realtime)
fi

log=$out/objects.lcmlog
echo "== clutterseg --source $source =="
"$bin/src/daemon/clutterseg" --config config/clutterseg.yaml --source "$source" \
  --lcm-url "file://$log?mode=w" --png-dir "$out/overlays" "${extra[@]}"

echo "== objects published (decoded from $log) =="
"$bin/tools/clutterseg-listen" --lcm-url "file://$log?speed=0" --count 1000000 | tail -n 25
echo
echo "Overlay PNGs: $out/overlays   LCM log: $log"
