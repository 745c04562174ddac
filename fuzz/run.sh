#!/usr/bin/env bash
# Runs one fuzz target for a given time, single process, from the committed corpus.
#
#   fuzz/run.sh TARGET SECONDS      TARGET: obj | mtl | pipeline | ply | toml | gltf | textures
#
# Needs cargo-fuzz (`cargo install cargo-fuzz`). libFuzzer needs nightly compiler
# flags; RUSTC_BOOTSTRAP=1 lets the stable toolchain accept them. New inputs go to
# fuzz/work/<target> (not committed), crashes to fuzz/artifacts/<target>; the log,
# ending with the number of executions, to fuzz/work/<target>.log.
set -euo pipefail
if [ $# -ne 2 ]; then
    echo "usage: $0 obj|mtl|pipeline|ply|toml|gltf|textures SECONDS" >&2
    exit 2
fi
target=$1
seconds=$2
cd "$(dirname "$0")"
# glTF inputs carry a buffer and an image after the JSON: room for the seeds.
max_len=4096
[ "$target" = gltf ] && max_len=16384
mkdir -p "work/$target" "artifacts/$target"
export RUSTC_BOOTSTRAP=1
cargo fuzz build -O "$target"
# -rss_limit_mb catches memory blow-ups; -timeout catches hangs (seconds per input).
cargo fuzz run -O "$target" "work/$target" "corpus/$target" -- \
    -max_total_time="$seconds" -dict="dict/$target.dict" -max_len="$max_len" \
    -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 2>&1 | tee "work/$target.log"
