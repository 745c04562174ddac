#!/bin/sh
# Two builds of `raytracer` on the 10,000-dragon field, same run: whole `raytracer bench`
# processes alternated by farm-bench (NEW OLD NEW OLD ...), each run's JSON kept, then
# the median and range of the pairwise ratios of every CPU rate (new / old).
#
#   bench/instancing/ab_field.sh NEW_BINARY OLD_BINARY [PAIRS]
#
# Needs bench/work/field.toml from bench/instancing/make_field.py.
set -eu
new=$(realpath "$1"); old=$(realpath "$2"); pairs=${3:-5}
here=$(dirname "$(realpath "$0")")
out=$(mktemp -d)
cd "$here/../work"
C="--width 1024 --height 768 --fov 45 --look-from 0.09,0.21,0.27 --look-to=-0.005,0.12,-0.005 --depth 8 --threads 1 --repeat 1"
farm-bench -n "$pairs" --timeout 3600 \
    --vs "sh -c 'exec $old bench field.toml $C >>$out/old.json 2>&1'" \
    -- sh -c "exec $new bench field.toml $C >>$out/new.json 2>&1"
python3 "$here/ratios.py" "$out/new.json" "$out/old.json"
uptime
