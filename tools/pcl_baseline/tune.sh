#!/usr/bin/env bash
# Tunes PCL's supervoxels + LCCP (clutterseg-pcl-baseline --method lccp) on mOSD learn and scores
# the chosen setting beside clutterseg's defaults per category, in one run.
#   grid A: extended convexity on/off x concavity 10/15/20/25/30/35 deg x sanity on/off x
#           single-camera transform on/off (voxel 7.5 mm, seed 30 mm, colour 0, spatial 1,
#           normal 4);
#   grid B: voxel 5/7.5/10 mm x seed 20/30/40 mm around the best point of grid A on mOSD
#           learn, then concavity 15/20/25/30 deg, then normal importance 1/4/8, each around the
#           best point so far.
# Every grid point is scored on mosd-learn and mosd-clutter (convention mosd-parts, or
# $GT_CONVENTION: mosd-objects tunes and scores on whole objects); the score
# is the mean over frames of (WOv + F1) / 2. The best point on mosd-learn and clutterseg's
# defaults are then scored on every category and on the synthetic sets (rooms seed 7 x30 and
# seed 101 x20, piles seeds 2001 and 2002 x15 with 10-20 objects, convention plain). Also a
# leave-one-category-out table: for each mOSD category, PCL's best grid point on the other five
# categories scored on the held-out one.
# Usage: [GT_CONVENTION=mosd-objects] tools/pcl_baseline/tune.sh [BUILD_DIR] [OUT_DIR] [stage...]
#        (defaults: build/pcl, out/pcl_tune, stages: a b final report)
# Resumable: a point whose CSVs exist is not run again. Runs two points at a time (PCL_JOBS).
set -euo pipefail
cd "$(dirname "$0")/../.."
build=${1:-build/pcl}
out=${2:-out/pcl_tune}
shift 2 2> /dev/null || shift $#
stages=("$@")
[ ${#stages[@]} -gt 0 ] || stages=(a b final report)
jobs=${PCL_JOBS:-2}
data=$(tools/data_root.sh) || { echo "no real data found: run tools/fetch_data.sh" >&2; exit 1; }
pcl=$build/tools/clutterseg-pcl-baseline
seg=$build/tools/clutterseg-segment
ev=$build/tools/clutterseg-eval
synth=$build/tools/clutterseg-synth
mkdir -p "$out"

set_input() {  # set name -> "input_dir convention"
  case $1 in
    learn) echo "$data/mosd-learn ${GT_CONVENTION:-mosd-parts}" ;;
    clutter) echo "$data/mosd-clutter ${GT_CONVENTION:-mosd-parts}" ;;
    *) echo "$out/$1 plain" ;;
  esac
}

# One point: tag, space-separated sets, then the segmenting command's options. "seg" as the
# first option runs clutterseg-segment with the rest, otherwise clutterseg-pcl-baseline.
run_point() {
  local tag=$1 sets=$2
  shift 2
  local set in conv dir
  for set in $sets; do
    [ -s "$out/$tag.$set.csv" ] && continue
    read -r in conv <<< "$(set_input "$set")"
    dir=$out/pcd.$tag.$set
    if [ "${1:-}" = seg ]; then
      "$seg" "$in" "$dir" -q "${@:2}" > /dev/null
    else
      "$pcl" "$in" "$dir" --method lccp --quiet "$@" > /dev/null
    fi
    "$ev" "$in" "$dir" --gt-convention "$conv" -q --csv "$out/$tag.$set.csv.tmp" > /dev/null
    mv "$out/$tag.$set.csv.tmp" "$out/$tag.$set.csv"
    rm -rf "${dir:?}"
  done
}
export -f run_point set_input
export out data pcl seg ev

# Grid points as lines "tag<TAB>options"; run in parallel on learn and clutter.
run_lines() {
  while IFS=$'\t' read -r tag opts; do
    printf '%s\0' "run_point '$tag' 'learn clutter' $opts"
  done | xargs -0 -P "$jobs" -I{} bash -c '{}'
}

grid_a() {
  local ext con san sct tag opts
  for ext in on off; do
    for con in 10 15 20 25 30 35; do
      for san in on off; do
        for sct in on off; do
          tag=lccp_ext-${ext}_con-${con}_san-${san}_sct-${sct}_vox-0.0075_seed-0.03_nrm-4
          opts="--concavity $con"
          [ $ext = off ] && opts+=" --no-extended"
          [ $san = off ] && opts+=" --no-sanity"
          [ $sct = on ] && opts+=" --single-camera-transform"
          printf '%s\t%s\n' "$tag" "$opts"
        done
      done
    done
  done
}

summary() {  # mode [args] -> see the Python below
  python3 tools/pcl_baseline/tune_summary.py "$out" "$@"
}

for stage in "${stages[@]}"; do
  case $stage in
    a) grid_a | run_lines ;;
    b)
      best=$(summary best-learn)
      base=${best%_vox-*}
      lines=""
      for vox in 0.005 0.0075 0.01; do
        for sd in 0.02 0.03 0.04; do
          lines+="${base}_vox-${vox}_seed-${sd}_nrm-4"$'\n'
        done
      done
      printf '%s' "$lines" | while read -r tag; do printf '%s\t%s\n' "$tag" "$(summary options "$tag")"; done | run_lines
      best=$(summary best-learn)
      for con in 15 20 25 30; do
        tag=${best%%_con-*}_con-${con}_${best#*_con-*_}
        printf '%s\t%s\n' "$tag" "$(summary options "$tag")"
      done | run_lines
      best=$(summary best-learn)
      for nrm in 1 8; do
        tag=${best%_nrm-*}_nrm-$nrm
        printf '%s\t%s\n' "$tag" "$(summary options "$tag")"
      done | run_lines
      ;;
    final)
      for s in 7:30 101:20; do
        [ -d "$out/synth${s%:*}" ] || "$synth" --out "$out/synth${s%:*}" --count "${s#*:}" --seed "${s%:*}" > /dev/null
      done
      for s in 2001 2002; do
        [ -d "$out/p$s" ] || "$synth" --out "$out/p$s" --count 15 --seed "$s" --objects 10:20 > /dev/null
      done
      best=$(summary best-learn)
      printf '%s\0' "run_point clutterseg_defaults 'learn clutter synth7 synth101 p2001 p2002' seg" \
        "run_point '$best' 'synth7 synth101 p2001 p2002' $(summary options "$best")" |
        xargs -0 -P "$jobs" -I{} bash -c '{}'
      ;;
    report) summary report ;;
    *) echo "unknown stage $stage" >&2; exit 1 ;;
  esac
done
