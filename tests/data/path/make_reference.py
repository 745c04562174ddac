#!/usr/bin/env python3
"""Renders tests/data/path/cornell.obj with Mitsuba 3's path tracer: the reference
image that tests/path.rs compares our path mode with, and the noise Mitsuba shows
against that reference at the test's sample count.

    pip install mitsuba          # llvm variants need Debian's libllvm19
    python3 tests/data/path/make_reference.py

Writes reference.exr (linear RGB, REFERENCE_SPP samples per pixel) and noise.toml
(block errors of independent Mitsuba renders at each of TEST_SPP samples per pixel
against the reference: NOISE_SEEDS renders each). The scene maps one to one onto Mitsuba plugins: `al0 * Kd` is a
two-sided `diffuse`, `al1` a `conductor` with `material = "none"`, `al2` with `Ni` a
`dielectric`, `Ke` an `area` emitter on a black surface; a box pixel filter.
"""

import os
import sys
import tempfile

import mitsuba as mi

HERE = os.path.dirname(os.path.abspath(__file__))
WIDTH, HEIGHT = 64, 48
FOV = 40.0
LOOK_FROM, LOOK_TO, UP = [0.0, 1.0, 3.4], [0.0, 1.0, 0.0], [0.0, 1.0, 0.0]
MAX_DEPTH = 64
REFERENCE_SPP = 16384
TEST_SPP = [64, 1024]
NOISE_SEEDS = 6
BLOCK = 4


def parse_mtl(path):
    materials, current = {}, None
    for line in open(path):
        words = line.split()
        if not words or words[0].startswith("#"):
            continue
        if words[0] == "newmtl":
            current = materials.setdefault(
                words[1], {"Kd": [0, 0, 0], "Ke": [0, 0, 0], "al": [1, 0, 0], "Ni": 1.0}
            )
        elif words[0] in ("Kd", "Ke", "al"):
            current[words[0]] = [float(w) for w in words[1:4]]
        elif words[0] == "Ni":
            current["Ni"] = float(words[1])
    return materials


def parse_obj(path):
    """(positions, {material: [triangles]}, [(center, radius, material)], mtllib)."""
    positions, groups, spheres, material, mtllib = [], {}, [], None, None
    for line in open(path):
        words = line.split()
        if not words or words[0].startswith("#"):
            continue
        if words[0] == "mtllib":
            mtllib = words[1]
        elif words[0] == "usemtl":
            material = words[1]
        elif words[0] == "v":
            positions.append([float(w) for w in words[1:4]])
        elif words[0] == "f":
            ids = [int(w.split("/")[0]) - 1 for w in words[1:]]
            for i in range(1, len(ids) - 1):
                groups.setdefault(material, []).append((ids[0], ids[i], ids[i + 1]))
        elif words[0] == "S":
            x, y, z, r = (float(w) for w in words[1:5])
            spheres.append(([x, y, z], r, material))
    return positions, groups, spheres, mtllib


def bsdf(m):
    kd = [m["al"][0] * c for c in m["Kd"]]
    if m["al"][1] > 0:
        return {"type": "conductor", "material": "none",
                "specular_reflectance": {"type": "rgb", "value": [m["al"][1]] * 3}}
    if m["al"][2] > 0:
        return {"type": "dielectric", "int_ior": m["Ni"], "ext_ior": 1.0,
                "specular_reflectance": {"type": "rgb", "value": [m["al"][2]] * 3},
                "specular_transmittance": {"type": "rgb", "value": [m["al"][2]] * 3}}
    return {"type": "twosided",
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": kd}}}


def write_ply(path, positions, triangles):
    used = sorted({i for t in triangles for i in t})
    index = {v: k for k, v in enumerate(used)}
    with open(path, "w") as f:
        f.write("ply\nformat ascii 1.0\n")
        f.write(f"element vertex {len(used)}\nproperty float x\nproperty float y\nproperty float z\n")
        f.write(f"element face {len(triangles)}\nproperty list uchar int vertex_indices\nend_header\n")
        for v in used:
            f.write(" ".join(repr(c) for c in positions[v]) + "\n")
        for t in triangles:
            f.write("3 " + " ".join(str(index[i]) for i in t) + "\n")


def scene_dict(folder, spp, seed):
    positions, groups, spheres, mtllib = parse_obj(os.path.join(HERE, "cornell.obj"))
    materials = parse_mtl(os.path.join(HERE, mtllib))
    try:
        to_world = mi.ScalarTransform4f().look_at(origin=LOOK_FROM, target=LOOK_TO, up=UP)
    except TypeError:
        to_world = mi.ScalarTransform4f.look_at(origin=LOOK_FROM, target=LOOK_TO, up=UP)
    scene = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": MAX_DEPTH, "rr_depth": 5},
        "sensor": {
            "type": "perspective", "fov": FOV, "fov_axis": "y", "to_world": to_world,
            "film": {"type": "hdrfilm", "width": WIDTH, "height": HEIGHT,
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": spp, "seed": seed},
        },
    }
    for name, triangles in groups.items():
        path = os.path.join(folder, f"{name}.ply")
        write_ply(path, positions, triangles)
        shape = {"type": "ply", "filename": path, "face_normals": True, "bsdf": bsdf(materials[name])}
        if any(materials[name]["Ke"]):
            shape["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": materials[name]["Ke"]}}
        scene[f"mesh_{name}"] = shape
    for k, (center, radius, name) in enumerate(spheres):
        scene[f"sphere_{k}"] = {"type": "sphere", "center": center, "radius": radius,
                                "bsdf": bsdf(materials[name])}
    return scene


def block_errors(image, reference):
    """Relative error of each BLOCK x BLOCK block's mean (over pixels and channels):
    the metric tests/path.rs applies to our render."""
    errors = []
    for by in range(0, HEIGHT, BLOCK):
        for bx in range(0, WIDTH, BLOCK):
            a = image[by:by + BLOCK, bx:bx + BLOCK, :].mean()
            r = reference[by:by + BLOCK, bx:bx + BLOCK, :].mean()
            errors.append(abs(a - r) / max(r, 1e-3))
    errors.sort()
    return sum(errors) / len(errors), errors[int(0.95 * (len(errors) - 1))]


def main():
    import numpy as np
    variant = os.environ.get("MITSUBA_VARIANT", "llvm_ad_rgb")
    mi.set_variant(variant)
    with tempfile.TemporaryDirectory() as folder:
        reference = np.array(mi.render(mi.load_dict(scene_dict(folder, REFERENCE_SPP, 0))))
        mi.Bitmap(reference).write(os.path.join(HERE, "reference.exr"))
        noise = {}
        for spp in TEST_SPP:
            noise[spp] = []
            for seed in range(1, NOISE_SEEDS + 1):
                scene = mi.load_dict(scene_dict(folder, spp, seed))
                noise[spp].append(block_errors(np.array(mi.render(scene, seed=seed)), reference))
    with open(os.path.join(HERE, "noise.toml"), "w") as f:
        f.write(f"# Written by make_reference.py with Mitsuba {mi.__version__} ({variant}).\n")
        f.write(f"# Block errors ({BLOCK}x{BLOCK} blocks, relative) of {NOISE_SEEDS} Mitsuba renders per\n")
        f.write(f"# sample count against reference.exr ({REFERENCE_SPP} spp).\n")
        f.write(f"width = {WIDTH}\nheight = {HEIGHT}\nfov = {FOV}\nmax_depth = {MAX_DEPTH}\n")
        f.write(f"look_from = {LOOK_FROM}\nlook_to = {LOOK_TO}\nblock = {BLOCK}\n")
        f.write(f"reference_spp = {REFERENCE_SPP}\n")
        for spp, rows in noise.items():
            f.write(f"\n[[noise]]\nspp = {spp}\n")
            f.write(f"mitsuba_mean = {[round(float(m), 5) for m, _ in rows]}\n")
            f.write(f"mitsuba_p95 = {[round(float(p), 5) for _, p in rows]}\n")
    print(open(os.path.join(HERE, "noise.toml")).read())


if __name__ == "__main__":
    sys.exit(main())
