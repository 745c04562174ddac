#!/usr/bin/env bash
# Work per ray on Embree's side (BENCHMARKS.md, "Instancing", the counts table): node
# visits of the instance tree and inside the copies, copies entered, leaves and
# Triangle4 blocks tested, single rays, one thread. Builds Embree 3.13.5 from its
# source (a checkout of the v3.13.5 tag) with EMBREE_STAT_COUNTERS and
# stat_counters.patch (counters by level, printed as absolute numbers at exit), only
# SSE2 and AVX-512 (what Debian's build runs on this machine), into PREFIX once
# (10-20 minutes on two cores; needs cmake), then traces each kind's single rays of
# RAYS.bin (`raytracer bench ... --dump-rays`) once:
#
#   bench/embree/count.sh EMBREE_SRC PREFIX RAYS.bin [--mesh MESH.bin --instances FIELD.npy]
#
# Per kind it prints the hit count and the counters: #user_abs1 instance-tree nodes,
# 2 other top-level nodes, 3 nodes inside copies, 4 copies entered, 5 leaves inside
# copies, 6 Triangle4 blocks inside copies, 8 other top-level leaves (divide by the
# rays). Ours: bench/instancing/walk_counters.patch (a throwaway counting build).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
src=$(realpath "$1"); prefix=$(realpath -m "$2"); shift 2
if [[ ! -f $prefix/lib/libembree3.so ]]; then
    patch -d "$src" -p1 --forward <"$here/stat_counters.patch"
    cmake -S "$src" -B "$prefix/build" -DCMAKE_BUILD_TYPE=Release -DCMAKE_INSTALL_PREFIX="$prefix" \
        -DEMBREE_STAT_COUNTERS=ON -DEMBREE_TUTORIALS=OFF -DEMBREE_ISPC_SUPPORT=OFF \
        -DEMBREE_TASKING_SYSTEM=INTERNAL -DEMBREE_ISA_SSE2=ON -DEMBREE_ISA_SSE42=OFF \
        -DEMBREE_ISA_AVX=OFF -DEMBREE_ISA_AVX2=OFF -DEMBREE_ISA_AVX512=ON \
        -DEMBREE_GEOMETRY_CURVE=OFF -DEMBREE_GEOMETRY_SUBDIVISION=OFF -DEMBREE_GEOMETRY_POINT=OFF \
        -DEMBREE_GEOMETRY_GRID=OFF -DEMBREE_GEOMETRY_QUAD=OFF -DEMBREE_GEOMETRY_USER=OFF
    nice -n 10 make -C "$prefix/build" -j2 embree
    make -C "$prefix/build" install >/dev/null
fi
cc -O3 -march=native -fopenmp -I"$prefix/include" "$here/embree_bench.c" -L"$prefix/lib" \
    -lembree3 -o "$prefix/embree_bench_stats"
for kind in primary shadow incoherent occlusion; do
    LD_LIBRARY_PATH=$prefix/lib "$prefix/embree_bench_stats" "$@" --threads 1 --repeat 1 --only "$kind" |
        grep -E '^\{|#user_abs[1-8]|#abs'
done
