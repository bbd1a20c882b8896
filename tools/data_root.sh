#!/usr/bin/env bash
# Prints the folder of the real RGB-D data sets, searched as the tests search it:
# $CLUTTERSEG_DATA when set, else the checkout's data/ (what tools/fetch_data.sh fills), else
# ../shared/data beside the checkout. Exits 1, printing nothing, when none exists.
set -euo pipefail
checkout=$(cd "$(dirname "$0")/.." && pwd)
if [ -n "${CLUTTERSEG_DATA:-}" ]; then
  candidates=("$CLUTTERSEG_DATA")
else
  candidates=("$checkout/data" "$checkout/../shared/data")
fi
for d in "${candidates[@]}"; do
  if [ -d "$d" ]; then
    (cd "$d" && pwd)
    exit 0
  fi
done
exit 1
