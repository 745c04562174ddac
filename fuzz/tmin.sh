#!/usr/bin/env bash
# Minimizes a crashing input: fuzz/tmin.sh TARGET ARTIFACT [SECONDS]; prints the path
# of the smallest input that still fails.
set -euo pipefail
cd "$(dirname "$0")"
export RUSTC_BOOTSTRAP=1
cargo fuzz tmin -O "$1" "$2" -- -max_total_time="${3:-60}" 2>&1 \
    | grep -a -A2 '^Minimized artifact:' | tail -1 | tr -d '[:space:]'
