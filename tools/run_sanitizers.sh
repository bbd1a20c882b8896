#!/usr/bin/env bash
# Runs the test suite under the sanitizers: ASan+UBSan (preset asan) and/or TSan (preset tsan).
#
# Usage: tools/run_sanitizers.sh [asan|tsan|all]          (default: all)
#
# For each sanitizer: installs missing dependencies (tools/install_deps.sh), configures and
# builds with the CMake preset (build/rel-asan, build/rel-tsan), then runs `ctest --preset`,
# which leaves out the soak, fuzz and slow labels. The test presets pass the suppression
# files tests/lsan.supp and tests/tsan.supp to every test (and test binaries carry the same
# defaults, exported to the processes they start). Prints one summary line per sanitizer and
# exits non-zero when any configure, build or test step fails.
#
# Environment: JOBS (parallel build and test jobs, default 2), CTEST_ARGS (extra ctest
# arguments, e.g. "-R daemon"), SKIP_DEPS=1 (do not run install_deps.sh).
set -uo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "${here}/.." && pwd)"
which="${1:-all}"
jobs="${JOBS:-2}"
case "${which}" in
  asan) sanitizers=(asan) ;;
  tsan) sanitizers=(tsan) ;;
  all) sanitizers=(asan tsan) ;;
  -h | --help)
    sed -n '2,14p' "$0" | sed 's/^# \{0,1\}//'
    exit 0
    ;;
  *)
    echo "run_sanitizers.sh: unknown argument '${which}' (expected asan, tsan or all)" >&2
    exit 2
    ;;
esac

if [ "${SKIP_DEPS:-0}" != "1" ]; then
  if ! "${here}/install_deps.sh"; then
    echo "run_sanitizers.sh: installing dependencies failed" >&2
    exit 1
  fi
fi

cd "${root}" || exit 1
summaries=()
status=0
for s in "${sanitizers[@]}"; do
  log_dir="${root}/build/rel-${s}"
  mkdir -p "${log_dir}"
  start=$(date +%s)
  result=""
  if ! cmake --preset "${s}" >"${log_dir}/run_sanitizers_configure.log" 2>&1; then
    result="configure FAILED (see ${log_dir}/run_sanitizers_configure.log)"
  elif ! cmake --build --preset "${s}" -j "${jobs}" >"${log_dir}/run_sanitizers_build.log" 2>&1; then
    tail -n 40 "${log_dir}/run_sanitizers_build.log" >&2
    result="build FAILED (see ${log_dir}/run_sanitizers_build.log)"
  else
    # shellcheck disable=SC2086  # CTEST_ARGS is split on purpose
    ctest --preset "${s}" -j "${jobs}" ${CTEST_ARGS:-} 2>&1 | tee "${log_dir}/run_sanitizers_ctest.log"
    rc=${PIPESTATUS[0]}
    line=$(grep -E '^[0-9]+% tests passed' "${log_dir}/run_sanitizers_ctest.log" | tail -n 1)
    if [ "${rc}" -eq 0 ]; then
      result="${line:-passed}"
    else
      result="FAILED: ${line:-ctest exit code ${rc}} (see ${log_dir}/run_sanitizers_ctest.log)"
    fi
  fi
  elapsed=$(($(date +%s) - start))
  case "${result}" in
    *FAILED*) status=1 ;;
  esac
  summaries+=("${s}: ${result}, ${elapsed} s")
done

echo
for line in "${summaries[@]}"; do echo "sanitizers: ${line}"; done
exit "${status}"
