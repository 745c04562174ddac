#!/usr/bin/env bash
# Builds bench/embree/embree_bench (needs Debian's libembree-dev: apt-get install
# libembree-dev) into bench/work/embree_bench.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
out=${1:-$here/../work/embree_bench}
mkdir -p "$(dirname "$out")"
[[ -f /usr/include/embree3/rtcore.h ]] ||
    { echo "bench/embree/build.sh: error: needs libembree-dev (apt-get install libembree-dev)" >&2; exit 2; }
cc -O3 -march=native -fopenmp -Wall -Wextra "$here/embree_bench.c" -lembree3 -o "$out"
echo "$out"
