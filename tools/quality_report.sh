#!/usr/bin/env bash
# Measures segmentation quality (METHOD.md section 7) of clutterseg's default configuration,
# the paper's configuration and one-change-at-a-time ablations, on the mOSD learn frames
# (part and object labels) and on synthetic scenes, and prints Markdown tables.
# Usage: tools/quality_report.sh [BUILD_DIR] [OUT_DIR] [PCL_BUILD_DIR]
#   (defaults: build/release, out/quality, build/pcl). When PCL_BUILD_DIR holds
#   tools/clutterseg-pcl-baseline (cmake --preset pcl), PCL's baselines are scored too.
# Needs the real set mosd-learn (tools/fetch_data.sh; found as the tests find it:
# $CLUTTERSEG_DATA, data/, ../shared/data).
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build/release}
out=${2:-out/quality}
data=$(tools/data_root.sh) || { echo "no real data found: run tools/fetch_data.sh" >&2; exit 1; }
seg=$build/tools/clutterseg-segment
ev=$build/tools/clutterseg-eval
synth=$build/tools/clutterseg-synth
mkdir -p "$out"
if [ ! -d "$out/synth30" ]; then
  "$synth" --out "$out/synth30" --count 30 --seed 7 > /dev/null
fi

fmt() {  # last JSON line of clutterseg-eval -> "WOv | P | R | F1 | segments"
  python3 -c 'import json,sys; d=json.loads(sys.stdin.read().strip().splitlines()[-1]); print("%.3f | %.3f | %.3f | %.3f | %.1f" % (d["wov"], d["precision"], d["recall"], d["f1"], d["mean_segments"]))'
}

row() {  # name, then clutterseg-segment options
  local name=$1; shift
  local dir=$out/$(echo "$name" | tr -c 'a-zA-Z0-9\n' '_')
  "$seg" "$data/mosd-learn" "$dir/mosd" -q --force "$@" > /dev/null
  "$seg" "$out/synth30" "$dir/synth" -q --force "$@" > "$dir.segment.json"
  local parts objects syn ms
  parts=$("$ev" "$data/mosd-learn" "$dir/mosd" --gt-convention mosd-parts -q | fmt)
  objects=$("$ev" "$data/mosd-learn" "$dir/mosd" --gt-convention mosd-objects -q | fmt)
  syn=$("$ev" "$out/synth30" "$dir/synth" --gt-convention plain -q | fmt)
  echo "| $name | $parts | $objects | $syn |"
}

echo "| configuration | mOSD parts WOv | P | R | F1 | seg/frame | mOSD objects WOv | P | R | F1 | seg/frame | synthetic WOv | P | R | F1 | seg/frame |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
row "clutterseg defaults"
row "paper as written (config/paper.yaml)" --config config/paper.yaml
row "concavity tolerance 10 deg (LCCP)" --set linkage.concavity_tolerance_deg=10
row "cut edges on patch-type change (paper)" --set linkage.cut_on_type_change=true
row "extended convexity on" --set linkage.use_extended_convexity=true
row "sanity criterion off" --set linkage.use_sanity_criterion=false
row "plane seeds: single patch, flattest first, 64 trials (paper)" --set planes.seed_neighborhood_m=0 --set planes.accept_largest_first=false --set planes.max_candidate_trials=64 --set planes.max_seed_curvature=0.01
row "rho 15 mm, inlier angle 15 deg" --set planes.inlier_distance_m=0.015 --set planes.inlier_angle_deg=15
row "no feature term (kappa_f = 0)" --set planes.feature_weight=0
row "distance-only data term (normal_mismatch_cost = 0)" --set planes.normal_mismatch_cost=0
row "keep segments below the support (margin 0)" --set objects.below_support_margin_m=0
row "depth range to 4 m" --set points.max_depth_m=4
row "2 supervoxel refinement iterations" --set supervoxel.refinement_iterations=2
row "1 growth region (VCCS)" --set supervoxel.growth_regions=1
row "snap object points within 5 mm of a support to background" --set objects.support_snap_distance_m=0.005

pcl=${3:-build/pcl}/tools/clutterseg-pcl-baseline
pcl_row() {  # name, then clutterseg-pcl-baseline options
  local name=$1; shift
  local dir=$out/pcl_$(echo "$name" | tr -c 'a-zA-Z0-9\n' '_')
  "$pcl" "$data/mosd-learn" "$dir/mosd" --quiet --times "$dir.mosd_times.jsonl" "$@" > /dev/null
  "$pcl" "$out/synth30" "$dir/synth" --quiet --times "$dir.synth_times.jsonl" "$@" > /dev/null
  local parts objects syn
  parts=$("$ev" "$data/mosd-learn" "$dir/mosd" --gt-convention mosd-parts -q | fmt)
  objects=$("$ev" "$data/mosd-learn" "$dir/mosd" --gt-convention mosd-objects -q | fmt)
  syn=$("$ev" "$out/synth30" "$dir/synth" --gt-convention plain -q | fmt)
  echo "| $name | $parts | $objects | $syn |"
}
if [ -x "$pcl" ]; then
  pcl_row "PCL 1.13 supervoxels + LCCP (issue parameters: extended + sanity)" --method lccp
  pcl_row "PCL 1.13 supervoxels + LCCP (no extended, single-camera transform)" --method lccp --no-extended --single-camera-transform
  pcl_row "PCL 1.13 organized planes + Euclidean clusters" --method planes-clusters
fi
