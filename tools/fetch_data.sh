#!/usr/bin/env bash
# Fetches the real RGB-D data sets that the `realdata` tests and the quality reports use, from
# their public upstream git repositories at pinned commits, into the checkout's git-ignored
# data/ folder (or $CLUTTERSEG_DATA when set). Only the listed paths are fetched: a shallow,
# blob-less, sparse fetch of each repository at its commit. Every file is checked against the
# SHA-256 committed in tools/data/manifest.tsv before its set is moved into place, so a set in
# data/ is either complete and verified or absent: a wrong checksum, a missing path or an
# interrupted fetch leaves nothing half-filled behind.
#
# Usage: tools/fetch_data.sh [options] [SET ...]      (no SET: every set of the manifest)
#   --list            print the sets, their file counts and licences, and exit
#   --verify          check the sets already there against the manifest (no fetch); without
#                     --dest, where the tests look: $CLUTTERSEG_DATA, data/, ../shared/data
#   --dest DIR        destination (default: $CLUTTERSEG_DATA, else <checkout>/data)
#   --upstream URL    prefix of the repositories' URLs, "<URL>/<owner>/<name>" (default:
#                     $CLUTTERSEG_DATA_UPSTREAM, else https://github.com); a local mirror works
#   --manifest FILE   the file list (default tools/data/manifest.tsv)
#   --sets FILE       the sets' descriptions and licences (default tools/data/sets.tsv)
#   --force           fetch again sets that are already present and verified
# Environment: GIT names the git executable (default git).
# Exit codes: 0 every requested set present and verified; 1 a fetch or a check failed (the
# message names the set, file and repository); 2 bad command line; 130/143 interrupted.
set -euo pipefail

here=$(cd "$(dirname "$0")" && pwd)
checkout=$(dirname "$here")
manifest="$here/data/manifest.tsv"
sets_file="$here/data/sets.tsv"
dest=${CLUTTERSEG_DATA:-$checkout/data}
upstream=${CLUTTERSEG_DATA_UPSTREAM:-https://github.com}
git_exe=${GIT:-git}
mode=fetch
force=0
dest_given=0
wanted=()

usage() {
  sed -n '/^# Usage:/,/^# Exit codes/p' "$0" | sed 's/^# \{0,1\}//' >&2
  exit 2
}
while [ $# -gt 0 ]; do
  case "$1" in
    --list) mode=list ;;
    --verify) mode=verify ;;
    --force) force=1 ;;
    --dest) [ $# -ge 2 ] || usage; dest=$2; dest_given=1; shift ;;
    --upstream) [ $# -ge 2 ] || usage; upstream=${2%/}; shift ;;
    --manifest) [ $# -ge 2 ] || usage; manifest=$2; shift ;;
    --sets) [ $# -ge 2 ] || usage; sets_file=$2; shift ;;
    -h|--help) usage ;;
    -*) echo "fetch_data: unknown option '$1'" >&2; usage ;;
    *) wanted+=("$1") ;;
  esac
  shift
done
for f in "$manifest" "$sets_file"; do
  [ -r "$f" ] || { echo "fetch_data: cannot read $f" >&2; exit 2; }
done

# The manifest without comments: set, repository, commit, path, local path, sha256.
rows=$(grep -v '^#' "$manifest" | grep -v '^[[:space:]]*$' || true)
all_sets=$(printf '%s\n' "$rows" | cut -f1 | awk '!seen[$0]++')
if [ "${#wanted[@]}" -eq 0 ]; then
  mapfile -t wanted <<< "$all_sets"
fi
for s in "${wanted[@]}"; do
  printf '%s\n' "$all_sets" | grep -qxF -- "$s" ||
    { echo "fetch_data: no set '$s' in $manifest (sets: $(echo $all_sets))" >&2; exit 2; }
done

set_rows() { printf '%s\n' "$rows" | awk -F'\t' -v s="$1" '$1 == s'; }
licence_of() { awk -F'\t' -v s="$1" '$1 == s { print $3 }' "$sets_file"; }
about() { awk -F'\t' -v s="$1" '$1 == s { print $2 }' "$sets_file"; }

# Checks the files of set $1 under directory $2 against the manifest; prints each problem.
verify_set() {
  local set=$1 dir=$2 bad=0 repo commit path local sum got
  while IFS=$'\t' read -r _ repo commit path local sum; do
    if [ ! -f "$dir/$local" ]; then
      echo "  missing: $set/$local ($repo@${commit:0:12}:$path)"
      bad=1
      continue
    fi
    got=$(sha256sum "$dir/$local" | cut -d' ' -f1)
    if [ "$got" != "$sum" ]; then
      echo "  checksum mismatch: $set/$local ($repo@${commit:0:12}:$path): expected $sum, got $got"
      bad=1
    fi
  done < <(set_rows "$set")
  return $bad
}

case "$mode" in
  list)
    for s in "${wanted[@]}"; do
      printf '%-16s %3d files  %s\n%18s licence: %s\n' "$s" "$(set_rows "$s" | wc -l)" \
        "$(about "$s")" "" "$(licence_of "$s")"
    done
    exit 0
    ;;
  verify)
    if [ "$dest_given" -eq 0 ]; then dest=$("$here/data_root.sh" || echo "$dest"); fi
    [ -d "$dest" ] || { echo "fetch_data: no real data found at $dest: nothing to verify (tools/fetch_data.sh fetches it)" >&2; exit 1; }
    status=0
    for s in "${wanted[@]}"; do
      if out=$(verify_set "$s" "$dest/$s"); then
        echo "ok: $s ($(set_rows "$s" | wc -l) files verified in $dest/$s)"
      else
        echo "FAILED: $s in $dest/$s" >&2
        echo "$out" >&2
        status=1
      fi
    done
    exit $status
    ;;
esac

mkdir -p "$dest"
stage=$(mktemp -d "$dest/.fetch.XXXXXX")
cleanup() { rm -rf "$stage"; }
trap cleanup EXIT
# The handlers write to the script's own stderr (fd 3), also while git's output is redirected.
exec 3>&2
trap 'echo "fetch_data: interrupted; nothing of this run was kept" >&3; exit 130' INT
trap 'echo "fetch_data: terminated; nothing of this run was kept" >&3; exit 143' TERM

# Sets already present and verified are kept unless --force.
todo=()
for s in "${wanted[@]}"; do
  if [ "$force" -eq 0 ] && [ -d "$dest/$s" ] && verify_set "$s" "$dest/$s" > /dev/null; then
    echo "ok: $s already in $dest/$s and verified"
  else
    todo+=("$s")
  fi
done
[ "${#todo[@]}" -gt 0 ] || exit 0

# One shallow, blob-less, sparse fetch per repository and commit, of the paths of every set
# to fetch; $stage/repos/N holds the N-th one.
declare -A clone_of
declare -A failed_clone
n=0
todo_rows=$(for s in "${todo[@]}"; do set_rows "$s"; done)
while IFS=$'\t' read -r repo commit; do
  d="$stage/repos/$n"
  clone_of["$repo@$commit"]=$d
  n=$((n + 1))
  url="$upstream/$repo"
  echo "fetching $repo at ${commit:0:12} from $url"
  {
    "$git_exe" init -q "$d" &&
      "$git_exe" -C "$d" remote add origin "$url" &&
      "$git_exe" -C "$d" config core.sparseCheckout true &&
      printf '%s\n' "$todo_rows" |
      awk -F'\t' -v r="$repo" -v c="$commit" '$2 == r && $3 == c { print "/" $4 }' \
        > "$d/.git/info/sparse-checkout" &&
      "$git_exe" -C "$d" fetch -q --depth 1 --filter=blob:none origin "$commit" &&
      [ "$("$git_exe" -C "$d" rev-parse FETCH_HEAD)" = "$commit" ] &&
      "$git_exe" -C "$d" -c advice.detachedHead=false checkout -q FETCH_HEAD
  } > "$stage/git.log" 2>&1 || {
    echo "fetch_data: could not fetch $repo at $commit from $url:" >&2
    sed 's/^/  /' "$stage/git.log" >&2
    failed_clone["$repo@$commit"]=1
  }
done < <(printf '%s\n' "$todo_rows" | cut -f2,3 | awk '!seen[$0]++')

# Each set is assembled in the staging folder, verified, then moved into place whole.
status=0
for s in "${todo[@]}"; do
  echo "$s: $(about "$s")"
  echo "$s: licence: $(licence_of "$s")"
  part="$stage/sets/$s"
  ok=1
  while IFS=$'\t' read -r _ repo commit path local sum; do
    if [ -n "${failed_clone["$repo@$commit"]:-}" ]; then
      ok=0
      continue
    fi
    src="${clone_of["$repo@$commit"]}/$path"
    if [ ! -f "$src" ]; then
      echo "fetch_data: $s: path '$path' not found in $repo at $commit" >&2
      ok=0
      continue
    fi
    mkdir -p "$(dirname "$part/$local")"
    cp "$src" "$part/$local"
  done < <(set_rows "$s")
  if [ "$ok" -eq 1 ] && ! out=$(verify_set "$s" "$part"); then
    echo "fetch_data: $s does not match tools/data/manifest.tsv:" >&2
    echo "$out" >&2
    ok=0
  fi
  if [ "$ok" -eq 0 ]; then
    echo "FAILED: $s was not stored (nothing of it is in $dest)" >&2
    status=1
    continue
  fi
  {
    echo "SET:     $s: $(about "$s")"
    echo "LICENCE: $(licence_of "$s")"
    echo "FETCHED: $(date -u +%Y-%m-%dT%H:%M:%SZ) by tools/fetch_data.sh from $upstream"
    echo "FILES:   repository@commit:path -> file"
    set_rows "$s" | awk -F'\t' '{ print "  " $2 "@" $3 ":" $4 " -> " $5 }'
  } > "$part/PROVENANCE.txt"
  set_rows "$s" | awk -F'\t' '{ print $6 "  " $5 }' > "$part/SHA256SUMS"
  # Replace an old copy only once the new one is complete.
  if [ -e "$dest/$s" ]; then mv "$dest/$s" "$stage/old-$s"; fi
  mv "$part" "$dest/$s"
  echo "ok: $s ($(set_rows "$s" | wc -l) files verified) in $dest/$s"
done
exit $status
