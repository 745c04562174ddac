#!/usr/bin/env python3
"""Path mode against Mitsuba 3's path tracer on the same scene, same run.

    cargo build --release
    pip install mitsuba numpy        # llvm_ad_rgb needs Debian's libllvm19
    python3 bench/path_vs_mitsuba.py [--width 320 --height 240 --spp 64 --repeat 5]

Ours: the whole `raytracer render` process (load, build, render, write the PNG), timed
from outside. Mitsuba: `load_dict` + `render` inside one Python process whose JIT has
already compiled the scene's kernels (one render before timing), so neither its
start-up nor its compilation counts against it. The two alternate, `--repeat` times
each; medians are reported with samples (paths) per second.

The scene is tests/data/path/cornell.obj, converted for Mitsuba by
tests/data/path/make_reference.py (the same conversion as the test's reference).
"""

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(ROOT, "tests", "data", "path"))

import make_reference as ref  # noqa: E402
import mitsuba as mi  # noqa: E402


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--width", type=int, default=320)
    parser.add_argument("--height", type=int, default=240)
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--threads", type=int, default=0,
                        help="threads for both (0: every core): ours -j N, Dr.Jit's thread count N")
    parser.add_argument("--binary", default=os.path.join(ROOT, "target", "release", "raytracer"))
    args = parser.parse_args()
    ref.WIDTH, ref.HEIGHT = args.width, args.height
    variant = os.environ.get("MITSUBA_VARIANT", "llvm_ad_rgb")
    mi.set_variant(variant)
    if args.threads:
        import drjit as dr
        dr.set_thread_count(args.threads)
    ours_cmd = [
        args.binary, "render", os.path.join(ROOT, "tests", "data", "path", "cornell.obj"),
        "--mode", "path", "--width", str(args.width), "--height", str(args.height),
        "--fov", str(ref.FOV), "--look-from", ",".join(map(str, ref.LOOK_FROM)),
        "--look-to", ",".join(map(str, ref.LOOK_TO)), "--depth", str(ref.MAX_DEPTH),
        "--spp", str(args.spp), "-q", "-j", str(args.threads),
    ]
    ours, theirs = [], []
    with tempfile.TemporaryDirectory() as folder:
        out = os.path.join(folder, "ours.png")
        # Warm Mitsuba's JIT (kernels are cached per scene shape and sample count).
        mi.render(mi.load_dict(ref.scene_dict(folder, args.spp, 0)), spp=args.spp)
        for i in range(args.repeat):
            start = time.perf_counter()
            subprocess.run(ours_cmd + ["-o", out], check=True)
            ours.append(time.perf_counter() - start)
            start = time.perf_counter()
            image = mi.render(mi.load_dict(ref.scene_dict(folder, args.spp, i + 1)), spp=args.spp)
            mi.Bitmap(image)  # make sure the render is finished (Dr.Jit is lazy)
            theirs.append(time.perf_counter() - start)
    samples = args.width * args.height * args.spp
    a, b = statistics.median(ours), statistics.median(theirs)
    threads = args.threads or os.cpu_count()
    print(f"scene: tests/data/path/cornell.obj {args.width}x{args.height}, {args.spp} spp, max depth {ref.MAX_DEPTH}, {threads} thread(s) each")
    print(f"ours (whole process):          median {a:.3f} s  ({samples / a / 1e6:.2f} M samples/s)  runs {[round(t, 3) for t in ours]}")
    print(f"Mitsuba {mi.__version__} {variant} (warm): median {b:.3f} s  ({samples / b / 1e6:.2f} M samples/s)  runs {[round(t, 3) for t in theirs]}")
    print(f"Mitsuba / ours: {b / a:.2f}x")


if __name__ == "__main__":
    main()
