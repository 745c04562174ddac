#!/usr/bin/env bash
# Refreshes the committed corpus of a target from its work corpus (fuzz/work/TARGET,
# grown by run.sh): minimises the work corpus with `cargo fuzz cmin`, then keeps the
# reference-scene seeds (from seed.sh) plus COUNT (default 25) small inputs of the
# minimised set, picked evenly by size, so that the repository stays small.
#
#   fuzz/refresh-corpus.sh TARGET [COUNT]
set -euo pipefail
target=$1
count=${2:-25}
cd "$(dirname "$0")"
export RUSTC_BOOTSTRAP=1
cargo fuzz cmin -O "$target" "work/$target" >/dev/null 2>&1
rm -rf "corpus/$target"
./seed.sh >/dev/null
# Inputs of at most 1 KiB, smallest first; take every n-th to spread over sizes.
mapfile -t small < <(find "work/$target" -type f -size -1025c -printf '%s %p\n' | sort -n | cut -d' ' -f2-)
step=$(( ${#small[@]} / count ))
[ "$step" -ge 1 ] || step=1
for ((i = 0; i < ${#small[@]} && i / step < count; i += step)); do
    cp "${small[$i]}" "corpus/$target/"
done
ls "corpus/$target" | wc -l
