#!/usr/bin/env bash
# Seeds fuzz/corpus/<target> from the reference scenes: each OBJ (the large deer cut
# to its first 3 KB of whole lines), each MTL, and for `pipeline` each OBJ with its
# `mtllib` renamed to m.mtl, a NUL byte and its MTL text. Run once; later the corpus
# is refreshed by `cargo fuzz cmin` (see docs/fuzzing.md).
set -euo pipefail
cd "$(dirname "$0")"
scenes=../tests/data/reference/scenes
mkdir -p corpus/obj corpus/mtl corpus/pipeline
for obj in "$scenes"/*/*.obj; do
    name=$(basename "$(dirname "$obj")")
    if [ "$(wc -c < "$obj")" -gt 3072 ]; then
        text=$(head -c 3072 "$obj" | sed '$d')
    else
        text=$(cat "$obj")
    fi
    printf '%s\n' "$text" > "corpus/obj/$name.obj"
    mtl=$(ls "$(dirname "$obj")"/*.mtl)
    cp "$mtl" "corpus/mtl/$name.mtl"
    {
        printf '%s\n' "$text" | sed 's/^mtllib .*/mtllib m.mtl/'
        printf '\0'
        cat "$mtl"
    } > "corpus/pipeline/$name"
done
./seed_readers.py
