#!/usr/bin/env bash
# Per-category quality (METHOD.md section 7) of clutterseg's defaults, the previous defaults,
# the paper's configuration and one-change-at-a-time ablations of the clutter additions
# (docs/method.md section 7), on mOSD learn (boxes, stacked, occluded, cylindric), mOSD clutter
# (mixed, complex piles; test43 is an unorganized cloud) and two synthetic sets (seed 7, 30
# rooms, used in development; seed 101, 20 rooms, never tuned on). Prints a Markdown table of
# WOv / F1 per set and category and the merged-object count (the evaluator's
# under-segmentation count summed over mosd-clutter).
# Usage: tools/clutter_report.sh [BUILD_DIR] [OUT_DIR]   (defaults: build/release, out/clutter)
# Needs the real sets mosd-learn and mosd-clutter (tools/fetch_data.sh; found as the tests find
# them: $CLUTTERSEG_DATA, data/, ../shared/data). Per-frame CSVs
# stay in OUT_DIR/<row>.<set>.csv; the segmented PCDs are deleted after scoring.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build/release}
out=${2:-out/clutter}
data=$(tools/data_root.sh) || { echo "no real data found: run tools/fetch_data.sh" >&2; exit 1; }
seg=$build/tools/clutterseg-segment
ev=$build/tools/clutterseg-eval
synth=$build/tools/clutterseg-synth
mkdir -p "$out"
[ -d "$out/synth7" ] || "$synth" --out "$out/synth7" --count 30 --seed 7 > /dev/null
[ -d "$out/synth101" ] || "$synth" --out "$out/synth101" --count 20 --seed 101 > /dev/null

summarize() {  # row name, CSV prefix -> one Markdown row
  python3 - "$1" "$2" <<'EOF'
import csv, sys
sys.path.insert(0, 'tools')
from mosd_categories import category as cat
name, prefix = sys.argv[1:3]
def rows(s): return list(csv.DictReader(open(prefix + '.' + s + '.csv')))
def f(rs):
    n = len(rs)
    return '%.4f / %.4f' % (sum(float(r['wov']) for r in rs) / n, sum(float(r['f1']) for r in rs) / n)
L, C = rows('learn'), rows('clutter')
cells = [f(L)] + [f([r for r in L if cat(r['frame']) == c]) for c in ('boxes', 'stacked', 'occluded', 'cylindric')]
cells += [f(C)] + [f([r for r in C if cat(r['frame']) == c]) for c in ('mixed', 'complex')]
cells += [str(sum(int(r['under_segmented']) for r in C)), f(rows('synth7')), f(rows('synth101'))]
print('| ' + name + ' | ' + ' | '.join(cells) + ' |')
EOF
}

row() {  # name, then clutterseg-segment options
  local name=$1; shift
  local tag
  tag=$(echo "$name" | tr -c 'a-zA-Z0-9\n' '_')
  local dir=$out/$tag
  for set in learn clutter synth7 synth101; do
    local in conv
    case $set in
      learn) in=$data/mosd-learn; conv=mosd-parts ;;
      clutter) in=$data/mosd-clutter; conv=mosd-parts ;;
      *) in=$out/$set; conv=plain ;;
    esac
    "$seg" "$in" "$dir/$set" -q "$@" > /dev/null
    "$ev" "$in" "$dir/$set" --gt-convention $conv -q --csv "$out/$tag.$set.csv" > /dev/null
    rm -rf "${dir:?}/$set"
  done
  rmdir "$dir" 2> /dev/null || true
  summarize "$name" "$out/$tag"
}

echo "| configuration | learn | boxes | stacked | occluded | cylindric | clutter | mixed | complex | clutter merged | synthetic s7 | synthetic s101 |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|"
row "clutterseg defaults"
row "previous defaults (config/previous-defaults.yaml)" --config config/previous-defaults.yaml
row "paper as written (config/paper.yaml)" --config config/paper.yaml
row "without the plane-merge normal check" --set objects.plane_merge_max_pair_angle_deg=180
row "without support release" --set objects.support_release_fraction=0
row "without the release height rule" --set objects.support_release_min_height_m=0
row "without support reclaim" --set objects.support_reclaim_passes=0
row "without merging small groups" --set objects.merge_small_groups=false
row "without the depth-jump cut" --set linkage.depth_jump_rel=0
row "sanity criterion on every connection" --set linkage.sanity_min_angle_deg=0
row "normal importance 4" --set supervoxel.normal_importance=4
row "support: every ring kept (ring_min_cluster_px 0)" --set support.ring_min_cluster_px=0
row "optional: crease evidence from 25 deg" --set linkage.crease_min_angle_deg=25
row "optional: colour-gated concavity tolerance 60 deg (off by default)" --set linkage.color_concavity_tolerance_deg=60
row "optional: container insides joined (0.5, off by default)" --set objects.container_max_axis_offset_rel=0.5
row "without the colour cut" --set linkage.color_threshold=0
