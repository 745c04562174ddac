#!/usr/bin/env python3
"""Mitsuba 3 on the dragon scene: load the dragon PLY and build the scene (BVH), render
1024x768 at 1 spp with direct lighting from the two point lights, and read the OBJ (for
parsing speed). Prints one JSON object with medians.

The `llvm_ad_rgb` variant is used when it works here; Dr.Jit needs a libLLVM recent
enough for this CPU (LLVM 15 aborts on AVX-512 machines; run.sh points
DRJIT_LIBLLVM_PATH at LLVM 19). It is probed in a child process, because a failing LLVM
aborts the whole interpreter; otherwise `scalar_rgb` is used and the reason reported.
Set MITSUBA_VARIANT to force a variant.

Mitsuba has no Phong BSDF: the floor is `diffuse`, the dragon `roughplastic`. The
`direct` integrator takes 2 emitter samples and no BSDF samples per pixel, which with two
point lights traces two shadow rays per hit, as our renderer does.
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import time

import common

try:
    import drjit as dr
    import mitsuba as mi
except ImportError as err:
    common.skip("mitsuba", f"cannot import mitsuba ({err}); pip install mitsuba")

PROBE = """
import mitsuba as mi, drjit as dr
mi.set_variant("llvm_ad_rgb")
scene = mi.load_dict({"type": "scene", "s": {"type": "sphere"}, "i": {"type": "direct"},
    "sensor": {"type": "perspective", "film": {"type": "hdrfilm", "width": 8, "height": 8}}})
dr.eval(mi.render(scene, spp=1))
"""


def choose_variant() -> tuple[str, str]:
    """(variant, why) : llvm_ad_rgb when a small render in a child process succeeds."""
    forced = os.environ.get("MITSUBA_VARIANT")
    if forced:
        return forced, "set by MITSUBA_VARIANT"
    try:
        probe = subprocess.run(
            [sys.executable, "-c", PROBE], capture_output=True, text=True, timeout=300
        )
    except subprocess.TimeoutExpired:
        return "scalar_rgb", "llvm_ad_rgb probe timed out"
    if probe.returncode == 0:
        return "llvm_ad_rgb", "llvm_ad_rgb works here"
    lines = [l for l in (probe.stderr or "").splitlines() if "ERROR" in l or "rror" in l or "xception" in l]
    reason = lines[0][:160] if lines else f"exit code {probe.returncode}"
    return "scalar_rgb", f"llvm_ad_rgb failed here ({reason.strip()})"


def rgb(value) -> dict:
    return {"type": "rgb", "value": list(value)}


def scene_dict(dragon, floor) -> dict:
    camera = mi.ScalarTransform4f().look_at(
        origin=list(common.LOOK_FROM), target=list(common.LOOK_TO), up=[0, 1, 0]
    )
    scene = {
        "type": "scene",
        "integrator": {"type": "direct", "emitter_samples": 2, "bsdf_samples": 0},
        "sensor": {
            "type": "perspective",
            "fov": common.FOV_DEGREES,
            "fov_axis": "y",
            "to_world": camera,
            "sampler": {"type": "independent", "sample_count": 1},
            "film": {
                "type": "hdrfilm",
                "width": common.WIDTH,
                "height": common.HEIGHT,
                "rfilter": {"type": "box"},
            },
        },
        "dragon": dragon,
        "floor": floor,
    }
    for i, (position, intensity) in enumerate(common.LIGHTS):
        scene[f"light{i}"] = {"type": "point", "position": list(position), "intensity": rgb(intensity)}
    return scene


def load(ply: str):
    """(ply ms, scene ms, scene): read the dragon, then build the scene and its BVH."""
    start = time.perf_counter()
    dragon = mi.load_dict(
        {
            "type": "ply",
            "filename": ply,
            "bsdf": {
                "type": "roughplastic",
                "diffuse_reflectance": rgb(common.DRAGON["Kd"]),
                "alpha": 0.1,
            },
        }
    )
    ply_ms = (time.perf_counter() - start) * 1000.0
    # Mitsuba's rectangle spans [-1, 1]^2 in z = 0 facing +z: turn it to face +y.
    floor = {
        "type": "rectangle",
        "to_world": mi.ScalarTransform4f()
        .translate([0, common.FLOOR_Y, 0])
        .rotate([1, 0, 0], -90),
        "bsdf": {"type": "diffuse", "reflectance": rgb(common.FLOOR["Kd"])},
    }
    start = time.perf_counter()
    scene = mi.load_dict(scene_dict(dragon, floor))
    dr.sync_thread()
    return ply_ms, (time.perf_counter() - start) * 1000.0, scene


def render(scene):
    image = mi.render(scene, spp=1)
    dr.eval(image)
    dr.sync_thread()
    return image


def main() -> None:
    args = common.parse_args(__doc__.splitlines()[0])
    if not args.ply:
        sys.exit("mitsuba_bench.py: error: --ply DRAGON.ply is required")
    variant, why = choose_variant()
    mi.set_variant(variant)
    # Quiet: the ASCII-PLY performance warning would otherwise print on every load.
    mi.set_log_level(mi.LogLevel.Error)

    loads = [load(args.ply) for _ in range(args.repeat)]
    ply_ms = statistics.median([l[0] for l in loads])
    scene_ms = statistics.median([l[1] for l in loads])
    scene = loads[-1][2]

    start = time.perf_counter()
    image = render(scene)
    first_ms = (time.perf_counter() - start) * 1000.0
    render_ms, _, image = common.timed(lambda: render(scene), args.repeat)
    if args.out:
        mi.util.write_bitmap(args.out, image)

    obj_bytes = os.path.getsize(args.obj)
    obj_ms, _, _ = common.timed(lambda: mi.load_dict({"type": "obj", "filename": args.obj}), args.repeat)

    common.emit(
        {
            "peer": "mitsuba",
            "version": f"mitsuba {mi.__version__}",
            "variant": variant,
            "variant_note": why,
            "ply_ms": common.ms(ply_ms),
            "scene_build_ms": common.ms(scene_ms),
            "load_ms": common.ms(ply_ms + scene_ms),
            "render_first_ms": common.ms(first_ms),
            "render_ms": common.ms(render_ms),
            "load_render_ms": common.ms(ply_ms + scene_ms + render_ms),
            "obj_bytes": obj_bytes,
            "obj_ms": common.ms(obj_ms),
            "obj_mb_per_s": round(obj_bytes / 1e6 / (obj_ms / 1000.0), 1),
        }
    )


if __name__ == "__main__":
    main()
