#!/usr/bin/env bash
# The README's quick-start times: a clean clone of this repository's HEAD in a fresh virtual
# environment, with an empty pip cache and an empty XDG_CACHE_HOME (no kernels cached); the
# two quick-start commands exactly as the README writes them, cold, then both again, warm.
#
#     bash tools/quickstart_time.sh [WORKDIR]      # default WORKDIR: /tmp/wbc-quickstart
#
# Prints each command's wall time, `wbc bench`'s own "N runs in S s" and pytest's summary;
# the full outputs are in WORKDIR/*.log.
set -u
repo="$(cd "$(dirname "$0")/.." && pwd)"
work="${1:-/tmp/wbc-quickstart}"
rm -rf "$work"
mkdir -p "$work/pip" "$work/cache"
git clone -q "$repo" "$work/clone" && cd "$work/clone" || exit 1
git log --oneline -1
python3.11 -m venv .venv && source .venv/bin/activate
export PIP_CACHE_DIR="$work/pip" XDG_CACHE_HOME="$work/cache"
elapsed() { python3 -c "import sys; print(f'{float(sys.argv[2]) - float(sys.argv[1]):.0f} s')" "$@"; }
for round in cold warm; do
    date -u +%H:%M:%S
    s=$(date +%s.%N)
    (python -m pip install -e ".[all]" && wbc bench --json results/bench.json --plots results/plots) \
        >"$work/$round-1.log" 2>&1
    rc=$?
    echo "$round 1: rc=$rc $(elapsed "$s" "$(date +%s.%N)"); $(grep -o '[0-9]* runs in [0-9.]* s' "$work/$round-1.log" | tail -1)"
    s=$(date +%s.%N)
    (python -m pip install -e ".[all,test]" && python -m pytest) >"$work/$round-2.log" 2>&1
    rc=$?
    echo "$round 2: rc=$rc $(elapsed "$s" "$(date +%s.%N)"); $(tail -1 "$work/$round-2.log")"
    uptime
done
