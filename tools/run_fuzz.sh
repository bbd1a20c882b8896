#!/usr/bin/env bash
# Fuzzes every libFuzzer target of tests/fuzz, one after the other, and reports per target the
# inputs executed, the coverage reached, the corpus size and the findings. Needs clang (the
# libFuzzer runtime comes with it); runs without CI.
#
# Usage: tools/run_fuzz.sh [SECONDS] [TARGET...]
#   SECONDS  how long each target runs (default 600)
#   TARGET   names from build/fuzz/tests/fuzz/fuzz_targets.txt (default: all of them)
#
# Configures build/fuzz with clang and -DCLUTTERSEG_FUZZ=ON when it is not configured yet
# (the whole build is then instrumented: sanitizer coverage, ASan, UBSan), builds the targets,
# then runs each target alone under `nice -n $NICE` on a work copy of its corpus
# (build/fuzz/tests/fuzz/corpus_work/TARGET; the seeds in tests/fuzz/corpus are read, never
# written). A crash, sanitizer report, leak, timeout (a single input over $TIMEOUT_S s) or
# out-of-memory (over $RSS_MB MiB) stops that target; its input is kept as
# build/fuzz/tests/fuzz/findings/TARGET-<kind>-<sha1> (reproduce: the target's executable
# with that file as its argument; after the fix, copy it into tests/fuzz/corpus/TARGET/ so
# that the `corpus` replay test guards against it). Logs: build/fuzz/tests/fuzz/logs/.
# The summary table (markdown, as in docs/reliability.md) is printed and written to
# build/fuzz/fuzz_results.md. Exit code: 0 when no target found anything, 1 otherwise, 2 on a
# usage or build error.
#
# Environment: BUILD_DIR (default build/fuzz), NICE (15), RSS_MB (2048), TIMEOUT_S (10),
# MAX_LEN (libFuzzer -max_len; default: libFuzzer's choice from the corpus), JOBS (build, 2).
set -uo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "${here}/.." && pwd)"
build="${BUILD_DIR:-${root}/build/fuzz}"
nice_level="${NICE:-15}"
rss_mb="${RSS_MB:-2048}"
timeout_s="${TIMEOUT_S:-10}"
jobs="${JOBS:-2}"

case "${1:-}" in
  -h | --help)
    sed -n '2,26p' "$0" | sed 's/^# \{0,1\}//'
    exit 0
    ;;
esac
seconds=600
if [ $# -ge 1 ] && [[ "$1" =~ ^[0-9]+$ ]]; then
  seconds="$1"
  shift
fi
if [ "${seconds}" -lt 1 ]; then
  echo "run_fuzz.sh: SECONDS must be at least 1" >&2
  exit 2
fi

if ! command -v clang++ > /dev/null; then
  echo "run_fuzz.sh: clang++ not found (libFuzzer comes with clang)" >&2
  exit 2
fi
if [ ! -f "${build}/CMakeCache.txt" ]; then
  launcher=()
  if command -v ccache > /dev/null; then
    launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
  fi
  if ! CC=clang CXX=clang++ nice -n "${nice_level}" cmake -S "${root}" -B "${build}" -G Ninja \
    -DCMAKE_BUILD_TYPE=Release -DCLUTTERSEG_WERROR=ON -DCLUTTERSEG_FUZZ=ON \
    -DCLUTTERSEG_BUILD_BENCHMARKS=OFF "${launcher[@]}"; then
    echo "run_fuzz.sh: configuring ${build} failed" >&2
    exit 2
  fi
elif ! grep -q '^CLUTTERSEG_FUZZ:BOOL=ON' "${build}/CMakeCache.txt"; then
  echo "run_fuzz.sh: ${build} is not a fuzz build (-DCLUTTERSEG_FUZZ=ON)" >&2
  exit 2
else
  nice -n "${nice_level}" cmake "${build}" > /dev/null || exit 2
fi

manifest="${build}/tests/fuzz/fuzz_targets.txt"
if [ ! -s "${manifest}" ]; then
  echo "run_fuzz.sh: ${manifest} is missing or empty (is the compiler clang?)" >&2
  exit 2
fi
declare -A exe_of corpus_of
all=()
while read -r name exe corpus; do
  [ -n "${name}" ] || continue
  all+=("${name}")
  exe_of["${name}"]="${exe}"
  corpus_of["${name}"]="${corpus}"
done < "${manifest}"
targets=("$@")
if [ ${#targets[@]} -eq 0 ]; then targets=("${all[@]}"); fi
build_targets=()
for t in "${targets[@]}"; do
  if [ -z "${exe_of[${t}]:-}" ]; then
    echo "run_fuzz.sh: unknown target '${t}' (known: ${all[*]})" >&2
    exit 2
  fi
  build_targets+=("${t}_fuzz")
done
if ! nice -n "${nice_level}" cmake --build "${build}" -j "${jobs}" --target "${build_targets[@]}"; then
  echo "run_fuzz.sh: building the fuzz targets failed" >&2
  exit 2
fi

out="${build}/tests/fuzz"
mkdir -p "${out}/logs" "${out}/findings"
results="${build}/fuzz_results.md"
{
  echo "| target | seconds | inputs executed | exec/s | coverage (edges / features) | corpus (inputs) | peak RSS (MiB) | findings |"
  echo "|---|---|---|---|---|---|---|---|"
} > "${results}"
status=0
for t in "${targets[@]}"; do
  work="${out}/corpus_work/${t}"
  mkdir -p "${work}"
  log="${out}/logs/${t}.log"
  before=$(find "${out}/findings" -name "${t}-*" -type f | wc -l)
  max_len=()
  if [ -n "${MAX_LEN:-}" ]; then max_len=(-max_len="${MAX_LEN}"); fi
  echo "run_fuzz.sh: ${t} for ${seconds} s (log ${log})"
  nice -n "${nice_level}" "${exe_of[${t}]}" -max_total_time="${seconds}" \
    -rss_limit_mb="${rss_mb}" -malloc_limit_mb="${rss_mb}" -timeout="${timeout_s}" \
    -print_final_stats=1 "${max_len[@]}" -artifact_prefix="${out}/findings/${t}-" \
    "${work}" "${corpus_of[${t}]}" > "${log}" 2>&1
  rc=$?
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "${log}" | tail -1)
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "${log}" | tail -1)
  peak=$(sed -n 's/^stat::peak_rss_mb: *//p' "${log}" | tail -1)
  # The last status line: "#N  REDUCE cov: E ft: F corp: C/..." (or DONE / pulse).
  last=$(grep -E '^#[0-9]+' "${log}" | tail -1)
  cov=$(sed -n 's/.* cov: \([0-9]*\).*/\1/p' <<< "${last}")
  ft=$(sed -n 's/.* ft: \([0-9]*\).*/\1/p' <<< "${last}")
  corpus=$(find "${work}" -type f | wc -l)
  after=$(find "${out}/findings" -name "${t}-*" -type f | wc -l)
  finding="none"
  if [ "${rc}" -ne 0 ] || [ "${after}" -gt "${before}" ]; then
    status=1
    kind=$(grep -m1 -oE 'ERROR: (AddressSanitizer|LeakSanitizer|UndefinedBehaviorSanitizer|libFuzzer): [a-z-]+|runtime error|fuzz invariant violated|deadly signal|timeout|out-of-memory' "${log}" | head -1 || true)
    artifact=$(sed -n 's/.*Test unit written to \(.*\)$/\1/p' "${log}" | tail -1)
    finding="**${kind:-exit ${rc}}** (${artifact:-see ${log}})"
  fi
  row="| \`${t}\` | ${seconds} | ${execs:-?} | ${rate:-?} | ${cov:-?} / ${ft:-?} | ${corpus} | ${peak:-?} | ${finding} |"
  echo "${row}" >> "${results}"
  echo "${row}"
done
echo
cat "${results}"
exit "${status}"
