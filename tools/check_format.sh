#!/usr/bin/env bash
# Fails when a tracked C++ file differs from what clang-format (the repository's .clang-format)
# makes of it; lists the files. Usage: tools/check_format.sh [REPO_ROOT]. Fix with
#   git ls-files '*.h' '*.cc' '*.hpp' '*.cpp' | xargs clang-format -i
set -euo pipefail
cd "${1:-$(dirname "$0")/..}"
command -v clang-format > /dev/null || { echo "check_format: clang-format not found" >&2; exit 2; }
bad=()
while IFS= read -r f; do
  clang-format --dry-run -Werror "$f" > /dev/null 2>&1 || bad+=("$f")
done < <(git ls-files '*.h' '*.cc' '*.hpp' '*.cpp' 2>/dev/null || find src drivers tools tests -name '*.h' -o -name '*.cc')
if [ "${#bad[@]}" -gt 0 ]; then
  printf 'not clang-formatted: %s\n' "${bad[@]}"
  echo "check_format: ${#bad[@]} file(s) need clang-format ($(clang-format --version))" >&2
  exit 1
fi
echo "check_format: every C++ file is clang-formatted"
