#!/usr/bin/env bash
# tools/fetch_data.sh against upstream git repositories built here (these machines reach no
# public host): a complete fetch, a second run that keeps what is verified, a wrong checksum,
# a path missing at the pinned commit, an unreachable repository and a fetch interrupted by
# SIGINT and SIGTERM. After every failure the destination holds no part of the failed set and
# no staging folder. Also checks the real manifest: every line well formed and every set
# described in tools/data/sets.tsv.
#
# Usage: fetch_data_test.sh SOURCE_DIR WORK_DIR
set -euo pipefail
src=$(realpath "$1")
work=$2
fetch="$src/tools/fetch_data.sh"
fail() { echo "FAIL: $*" >&2; exit 1; }
rm -rf "$work"
mkdir -p "$work"
work=$(realpath "$work")
export GIT_CONFIG_GLOBAL=/dev/null GIT_CONFIG_NOSYSTEM=1
export GIT_AUTHOR_NAME=t GIT_AUTHOR_EMAIL=t@localhost GIT_COMMITTER_NAME=t GIT_COMMITTER_EMAIL=t@localhost
unset CLUTTERSEG_DATA CLUTTERSEG_DATA_UPSTREAM

# 1. The real manifest and set descriptions.
grep -v '^#' "$src/tools/data/manifest.tsv" | awk -F'\t' '
  NF != 6 || length($3) != 40 || $3 !~ /^[0-9a-f]+$/ || length($6) != 64 || $6 !~ /^[0-9a-f]+$/ ||
  $5 ~ /^\// || $5 ~ /\.\./ {
    print "bad manifest line " NR ": " $0; bad = 1 }
  END { exit bad }' || fail "tools/data/manifest.tsv is malformed"
for s in $(grep -v '^#' "$src/tools/data/manifest.tsv" | cut -f1 | sort -u); do
  grep -q "^$s	" "$src/tools/data/sets.tsv" || fail "set $s has no line in tools/data/sets.tsv"
done
"$fetch" --list > "$work/list.txt" || fail "--list"
grep -q "licence:" "$work/list.txt" || fail "--list prints no licence"

# 2. Two upstream repositories with a few files each, in owner/name folders.
up="$work/upstream"
make_repo() {  # make_repo OWNER/NAME: an empty repository that serves partial clones
  mkdir -p "$up/$1"
  git -C "$up/$1" init -q
  git -C "$up/$1" config uploadpack.allowFilter true
  git -C "$up/$1" config uploadpack.allowAnySHA1InWant true
}
make_repo lab/frames
mkdir -p "$up/lab/frames/scenes/a" "$up/lab/frames/other"
head -c 300000 /dev/urandom > "$up/lab/frames/scenes/a/one.pcd"
echo "two" > "$up/lab/frames/scenes/a/two.json"
head -c 200000 /dev/urandom > "$up/lab/frames/other/unrelated.bin"
git -C "$up/lab/frames" add -A
git -C "$up/lab/frames" commit -q -m one
c1=$(git -C "$up/lab/frames" rev-parse HEAD)
sum_one=$(sha256sum "$up/lab/frames/scenes/a/one.pcd" | cut -d' ' -f1)
sum_two=$(sha256sum "$up/lab/frames/scenes/a/two.json" | cut -d' ' -f1)
# A later commit changes one.pcd: pinning the manifest to it gives a checksum mismatch.
echo "changed" >> "$up/lab/frames/scenes/a/one.pcd"
git -C "$up/lab/frames" commit -q -am two
c2=$(git -C "$up/lab/frames" rev-parse HEAD)
make_repo other/pngs
echo "png" > "$up/other/pngs/p.png"
git -C "$up/other/pngs" add -A
git -C "$up/other/pngs" commit -q -m p
c3=$(git -C "$up/other/pngs" rev-parse HEAD)
sum_p=$(sha256sum "$up/other/pngs/p.png" | cut -d' ' -f1)

sets="$work/sets.tsv"
printf 'alpha\ttwo frames\tBSD-3-Clause (test)\nbeta\tone png\tCC BY 4.0 (test)\n' > "$sets"
manifest() {  # manifest FILE ALPHA_COMMIT ALPHA_EXTRA_LINE
  {
    echo "# test manifest"
    printf 'alpha\tlab/frames\t%s\tscenes/a/one.pcd\tone.pcd\t%s\n' "$2" "$sum_one"
    printf 'alpha\tlab/frames\t%s\tscenes/a/two.json\tmeta/two.json\t%s\n' "$2" "$sum_two"
    [ -z "${3:-}" ] || printf '%s\n' "$3"
    printf 'beta\tother/pngs\t%s\tp.png\tp.png\t%s\n' "$c3" "$sum_p"
  } > "$1"
}
no_leftovers() {  # no staging folder, and set $2 absent when given
  if find "$1" -maxdepth 1 -name '.fetch.*' | grep -q .; then fail "staging left in $1"; fi
  if [ -n "${2:-}" ] && [ -e "$1/$2" ]; then fail "a part of the failed set $2 is in $1"; fi
}

# 3. A complete fetch, then a second run that keeps what is verified.
manifest "$work/good.tsv" "$c1"
dest="$work/data"
out=$("$fetch" --manifest "$work/good.tsv" --sets "$sets" --upstream "file://$up" --dest "$dest" 2>&1) ||
  fail "good fetch: $out"
echo "$out"
cmp -s "$dest/alpha/one.pcd" <(git -C "$up/lab/frames" show "$c1:scenes/a/one.pcd") ||
  fail "alpha/one.pcd differs from the pinned commit"
[ -f "$dest/alpha/meta/two.json" ] || fail "alpha/meta/two.json missing"
[ ! -e "$dest/alpha/unrelated.bin" ] && [ ! -e "$dest/alpha/other" ] || fail "unlisted files copied"
echo "$out" | grep -q "licence: BSD-3-Clause (test)" || fail "the licence of alpha was not printed"
grep -q "lab/frames@$c1:scenes/a/one.pcd -> one.pcd" "$dest/alpha/PROVENANCE.txt" ||
  fail "PROVENANCE.txt does not name the source"
(cd "$dest/alpha" && sha256sum -c --quiet SHA256SUMS) || fail "SHA256SUMS of alpha"
no_leftovers "$dest"
out=$("$fetch" --manifest "$work/good.tsv" --sets "$sets" --upstream "file:///nonexistent" \
  --dest "$dest" 2>&1) || fail "a second run must keep verified sets without fetching: $out"
echo "$out" | grep -q "ok: alpha already in" || fail "second run: $out"
"$fetch" --manifest "$work/good.tsv" --sets "$sets" --dest "$dest" --verify > /dev/null ||
  fail "--verify on a good copy"
echo corrupt >> "$dest/beta/p.png"
if out=$("$fetch" --manifest "$work/good.tsv" --sets "$sets" --dest "$dest" --verify 2>&1); then
  fail "--verify must fail on a corrupted file"
fi
echo "$out" | grep -q "checksum mismatch: beta/p.png" || fail "--verify message: $out"
"$fetch" --manifest "$work/good.tsv" --sets "$sets" --upstream "file://$up" --dest "$dest" beta \
  > /dev/null 2>&1 || fail "re-fetching a corrupted set"
"$fetch" --manifest "$work/good.tsv" --sets "$sets" --dest "$dest" --verify beta > /dev/null ||
  fail "the re-fetched set does not verify"

# A run that must fail: fetch_fails WHAT MANIFEST UPSTREAM DEST MESSAGE [SET...] runs the
# script, requires a non-zero exit, MESSAGE in its output and nothing of alpha stored.
fetch_fails() {
  local what=$1 man=$2 upstream=$3 dest=$4 message=$5
  shift 5
  if out=$("$fetch" --manifest "$man" --sets "$sets" --upstream "$upstream" --dest "$dest" \
    "$@" 2>&1); then
    fail "$what must fail"
  fi
  echo "$out" | grep -qF -- "$message" || fail "$what: expected '$message' in: $out"
  no_leftovers "$dest" alpha
}

# 4. A wrong checksum: the manifest pins the commit whose one.pcd changed.
manifest "$work/mismatch.tsv" "$c2"
fetch_fails "a checksum mismatch" "$work/mismatch.tsv" "file://$up" "$work/data-mismatch" \
  "checksum mismatch: alpha/one.pcd"
[ -f "$work/data-mismatch/beta/p.png" ] || fail "beta, which verified, must still be stored"

# 5. A path that the pinned commit does not have.
manifest "$work/missing.tsv" "$c1" \
  "$(printf 'alpha\tlab/frames\t%s\tscenes/a/absent.pcd\tabsent.pcd\t%s' "$c1" "$sum_one")"
fetch_fails "a missing path" "$work/missing.tsv" "file://$up" "$work/data-missing" \
  "path 'scenes/a/absent.pcd' not found in lab/frames at $c1" alpha

# 6. An unreachable repository (a fetch that dies on the network) and an unknown set.
dest="$work/data-unreachable"
fetch_fails "an unreachable upstream" "$work/good.tsv" "file://$work/nowhere" "$dest" \
  "could not fetch lab/frames"
[ ! -e "$dest/beta" ] || fail "beta stored from an unreachable upstream"
rc=0
"$fetch" --manifest "$work/good.tsv" --sets "$sets" --dest "$dest" gamma > /dev/null 2>&1 || rc=$?
[ "$rc" -eq 2 ] || fail "an unknown set must exit 2, got $rc"

# 7. Interrupted: git stalls in the middle of the fetch and the script's process group gets
# SIGINT (Ctrl-C) or SIGTERM.
cat > "$work/slow-git" << 'EOF'
#!/usr/bin/env bash
if [ "${2:-}" = fetch ] || [ "${3:-}" = fetch ]; then
  touch "$SLOW_GIT_MARK"
  sleep 60
fi
exec git "$@"
EOF
chmod +x "$work/slow-git"
for sig in INT TERM; do
  dest="$work/data-$sig"
  mark="$work/fetching-$sig"
  # A background job of a script starts with SIGINT ignored: restore the default first.
  SLOW_GIT_MARK=$mark GIT="$work/slow-git" setsid env --default-signal=INT,TERM \
    "$fetch" --manifest "$work/good.tsv" \
    --sets "$sets" --upstream "file://$up" --dest "$dest" > "$work/$sig.log" 2>&1 &
  pid=$!
  for _ in $(seq 1 300); do [ -e "$mark" ] && break; sleep 0.1; done
  [ -e "$mark" ] || fail "the fetch never started ($sig)"
  find "$dest" -maxdepth 1 -name '.fetch.*' | grep -q . || fail "no staging folder while fetching"
  kill -s "$sig" -- "-$pid"
  rc=0
  wait "$pid" || rc=$?
  [ "$rc" -ne 0 ] || fail "an interrupted fetch must exit non-zero ($sig)"
  grep -q "nothing of this run was kept" "$work/$sig.log" || fail "$sig message: $(cat "$work/$sig.log")"
  no_leftovers "$dest" alpha
  [ ! -e "$dest/beta" ] || fail "beta stored by an interrupted run ($sig)"
  echo "interrupted by SIG$sig: exit $rc, nothing kept"
done
echo "fetch_data_test: ok"
