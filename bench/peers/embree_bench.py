#!/usr/bin/env python3
"""Embree (Python binding `embreex`) on the dragon scene: BVH build, the same primary
rays as our `raytracer bench` (closest hit, no shading) and the same shadow rays
(any hit), timed as medians. Prints one JSON object.

The binding builds with all cores (Embree's TBB) but traces in one thread: its `run`
loops over `rtcIntersect1` / `rtcOccluded1` ray by ray.
"""

from __future__ import annotations

import importlib.metadata
import statistics
import sys
import time

import common

try:
    import numpy as np
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh
except ImportError as err:
    common.skip("embree", f"cannot import embreex/numpy ({err}); pip install embreex numpy")


def read_obj(path: str):
    """Vertices (float32, n x 3) and triangles (int32, m x 3, 0-based) of an OBJ.

    Polygons are split into the fan (P0, Pi, Pi+1), as SPEC.md says; everything but
    `v` and `f` is ignored (the lights are set up in code).
    """
    coords, triangles = [], []
    with open(path, encoding="ascii") as f:
        for line in f:
            if line.startswith("v "):
                coords.append(line[2:])
            elif line.startswith("f "):
                ids = [int(w.split("/")[0]) for w in line.split()[1:]]
                n_v = len(coords)
                ids = [i - 1 if i > 0 else n_v + i for i in ids]
                for k in range(1, len(ids) - 1):
                    triangles.append((ids[0], ids[k], ids[k + 1]))
    vertices = np.array(" ".join(coords).split(), dtype=np.float32).reshape(-1, 3)
    return vertices, np.array(triangles, dtype=np.int32)


def primary_rays():
    """One ray per pixel centre, row 0 at the top: SPEC.md's camera, in float32."""
    origin, right, up, backward = (np.array(v, dtype=np.float64) for v in common.camera_basis())
    half_h = np.tan(np.radians(common.FOV_DEGREES) / 2)
    half_w = half_h * common.WIDTH / common.HEIGHT
    xs = (2 * (np.arange(common.WIDTH) + 0.5) / common.WIDTH - 1) * half_w
    ys = (1 - 2 * (np.arange(common.HEIGHT) + 0.5) / common.HEIGHT) * half_h
    sx, sy = np.meshgrid(xs, ys)
    dirs = sx.reshape(-1, 1) * right + sy.reshape(-1, 1) * up - backward
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    origins = np.broadcast_to(origin, dirs.shape)
    return np.ascontiguousarray(origins, np.float32), np.ascontiguousarray(dirs, np.float32)


def shadow_rays(origins, dirs, hit):
    """From each primary hit, offset off the surface on the light's side, to each light;
    t_max is the distance to the light. The same construction as our Hit::spawn_ray_to."""
    mask = hit["primID"] >= 0
    o, d, t = origins[mask], dirs[mask], hit["tfar"][mask].reshape(-1, 1)
    p = o.astype(np.float64) + d * t
    n = hit["Ng"][mask].astype(np.float64)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    n[np.sum(n * d, axis=1) > 0] *= -1
    scale = common.SPAWN_OFFSET * np.maximum(np.abs(p).max(axis=1), 1.0)
    all_o, all_d, all_t = [], [], []
    for position, _ in common.LIGHTS:
        light = np.array(position, dtype=np.float64)
        side = np.where(np.sum((light - p) * n, axis=1) >= 0, 1.0, -1.0)
        start = p + n * (side * scale).reshape(-1, 1)
        to_light = light - start
        dist = np.linalg.norm(to_light, axis=1)
        all_o.append(start)
        all_d.append(to_light / dist.reshape(-1, 1))
        all_t.append(dist)
    return (
        np.ascontiguousarray(np.concatenate(all_o), np.float32),
        np.ascontiguousarray(np.concatenate(all_d), np.float32),
        np.ascontiguousarray(np.concatenate(all_t), np.float32),
    )


def build(vertices, triangles):
    """A committed scene; the first query commits (builds the BVH)."""
    scene = rtcore_scene.EmbreeScene()
    TriangleMesh(scene, vertices, triangles)
    start = time.perf_counter()
    scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32))
    return scene, (time.perf_counter() - start) * 1000.0


def main() -> None:
    args = common.parse_args(__doc__.splitlines()[0])
    vertices, triangles = read_obj(args.obj)

    # BVH build: the scene commit, without the binding's copy into Embree's buffers.
    build_ms, copy_ms = [], []
    for _ in range(args.repeat):
        start = time.perf_counter()
        scene, commit_ms = build(vertices, triangles)
        total = (time.perf_counter() - start) * 1000.0
        build_ms.append(commit_ms)
        copy_ms.append(total - commit_ms)
    build_median = statistics.median(build_ms)
    copy_median = statistics.median(copy_ms)

    origins, dirs = primary_rays()
    primary_ms, _, ids = common.timed(lambda: scene.run(origins, dirs), args.repeat)
    hit = scene.run(origins, dirs, output=1)
    hits = int(np.count_nonzero(hit["primID"] >= 0))
    if hits != int(np.count_nonzero(ids >= 0)):
        sys.exit("embree_bench.py: error: closest-hit runs disagree on the hit count")

    s_origins, s_dirs, s_tmax = shadow_rays(origins, dirs, hit)
    shadow_ms, _, occluded_ids = common.timed(
        lambda: scene.run(s_origins, s_dirs, dists=s_tmax, query="OCCLUDED"), args.repeat
    )
    occluded = int(np.count_nonzero(occluded_ids >= 0))

    common.emit(
        {
            "peer": "embree",
            "version": f"embreex {importlib.metadata.version('embreex')}",
            "triangles": int(len(triangles)),
            "copy_ms": common.ms(copy_median),
            "build_ms": common.ms(build_median),
            "primary_rays": int(len(dirs)),
            "primary_hits": hits,
            "primary_ms": common.ms(primary_ms),
            "primary_mrays_per_s": round(len(dirs) / primary_ms / 1000.0, 2),
            "shadow_rays": int(len(s_dirs)),
            "shadow_occluded": occluded,
            "shadow_occluded_fraction": round(occluded / len(s_dirs), 4),
            "shadow_ms": common.ms(shadow_ms),
            "shadow_mrays_per_s": round(len(s_dirs) / shadow_ms / 1000.0, 2),
            "threads": "build: all cores (TBB); rays: 1 (the binding loops rtcIntersect1)",
        }
    )


if __name__ == "__main__":
    main()
