#!/usr/bin/env python3
"""`raytracer.Scene.intersect` and `Scene.occluded` against embreex (the Embree binding
Python ray-casting code uses, as trimesh does) on the same rays and triangles, in one
process: the dragon's camera rays, its shadow rays towards the lights (occlusion) and
its incoherent bounce rays, as `raytracer bench` makes them; and building each side's
scene from the same arrays (`Scene.from_mesh`; Embree's build happens at its first query).

    python3 bench/python_rays.py [--runs 5] [SCENE]

SCENE defaults to bench/work/dragon-full.obj with the camera of bench/README.md. Needs
the package (`pip install .`), `pip install embreex` and target/release/raytracer
(which writes the triangles and rays, `raytracer bench --dump-rays`). The two calls
alternate RUNS times; rates are medians, per second of wall time and of CPU time (the
process's, all threads). Also counts the rays on which both give the same answer (the
same triangle, or both blocked or not).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import raytracer

ROOT = Path(__file__).resolve().parents[1]
CAMERA = [
    "--width", "1024", "--height", "768", "--fov", "45",
    "--look-from", "0.09,0.21,0.27", "--look-to=-0.005,0.12,-0.005", "--depth", "8",
]


def read_dump(path: Path):
    """Positions, triangles, primary, shadow and incoherent rays of a `--dump-rays` file
    (layout in bench/embree/embree_bench.c)."""
    data = path.read_bytes()
    assert data[:8] == b"RTBENCH1", path
    at = 8

    def take(dtype, count):
        nonlocal at
        array = np.frombuffer(data, dtype=dtype, count=count, offset=at)
        at += array.nbytes
        return array

    def count():
        return int(take("<u4", 1)[0])

    positions = take("<f4", 3 * count()).reshape(-1, 3)
    triangles = take("<u4", 3 * count()).reshape(-1, 3)
    primary = take("<f4", 7 * count()).reshape(-1, 7)
    take("<u4", 2 * count())  # primary packets
    shadow = take("<f4", 7 * count()).reshape(-1, 7)
    take("<u4", 2 * count())  # shadow packets
    incoherent = take("<f4", 7 * count()).reshape(-1, 7)
    return positions, triangles, primary, shadow, incoherent


def timed(call):
    wall, cpu = time.perf_counter(), time.process_time()
    result = call()
    return result, time.perf_counter() - wall, time.process_time() - cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", nargs="?", default=str(ROOT / "bench/work/dragon-full.obj"))
    parser.add_argument("--runs", type=int, default=5)
    args = parser.parse_args()
    from embreex import mesh_construction, rtcore_scene

    dump = ROOT / "bench/work/python_rays.bin"
    subprocess.run(
        [str(ROOT / "target/release/raytracer"), "bench", args.scene, *CAMERA, "--repeat", "1",
         "--dump-rays", str(dump)],
        check=True, capture_output=True,
    )
    positions, triangles, primary, shadow, incoherent = read_dump(dump)
    ours = raytracer.Scene(args.scene)
    faces = triangles.astype(np.int32)
    one_ray = (np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32))

    def embree_scene():
        scene = rtcore_scene.EmbreeScene()
        mesh_construction.TriangleMesh(scene, positions, faces)
        scene.run(*one_ray)  # Embree builds its BVH on the first query
        return scene

    # Building from arrays: ours through Scene.from_mesh, Embree's on its first query.
    builds = {"ours": ([], []), "embreex": ([], [])}
    built = {}
    for _ in range(args.runs):
        for name, make in [("ours", lambda: raytracer.Scene.from_mesh(positions, faces)),
                           ("embreex", embree_scene)]:
            built[name], wall, cpu = timed(make)
            builds[name][0].append(wall * 1e3)
            builds[name][1].append(cpu * 1e3)
    theirs = built["embreex"]

    print(f"{len(triangles):,} triangles; {args.runs} alternating runs; {os.cpu_count()} cores; "
          f"load average {os.getloadavg()[0]:.1f} at the start")
    print()
    print("| rays | ours (wall) | embreex (wall) | ours faster by | ours (CPU) | embreex (CPU) "
          "| ours faster by | same answer |")
    print("|---|---|---|---|---|---|---|---|")
    (ow, oc), (ew, ec) = ([statistics.median(r) for r in builds[k]] for k in ("ours", "embreex"))
    print(f"| build from arrays | {ow:.1f} ms | {ew:.1f} ms | {ew / ow:.2f}x | {oc:.1f} CPU-ms "
          f"| {ec:.1f} CPU-ms | {ec / oc:.2f}x | |")
    for label, rays in [("camera", primary), ("shadow", shadow), ("incoherent bounces", incoherent)]:
        origins = np.ascontiguousarray(rays[:, 0:3])
        directions = np.ascontiguousarray(rays[:, 3:6])
        t_max = np.ascontiguousarray(rays[:, 6])
        if label == "shadow":
            mine_call = lambda: ours.occluded(origins, directions, t_max)  # noqa: E731
            their_call = lambda: theirs.run(origins, directions, dists=t_max, query="OCCLUDED")  # noqa: E731
        else:
            mine_call = lambda: ours.intersect(origins, directions)  # noqa: E731
            their_call = lambda: theirs.run(origins, directions, output=1)  # noqa: E731
        rates = {"ours": ([], []), "embreex": ([], [])}
        for _ in range(args.runs):
            mine, wall, cpu = timed(mine_call)
            rates["ours"][0].append(len(rays) / wall / 1e6)
            rates["ours"][1].append(len(rays) / cpu / 1e6)
            other, wall, cpu = timed(their_call)
            rates["embreex"][0].append(len(rays) / wall / 1e6)
            rates["embreex"][1].append(len(rays) / cpu / 1e6)
        if label == "shadow":
            same = np.mean(mine == (other >= 0))
        else:
            same = np.mean(mine["primitive"] == np.where(other["geomID"] < 0, -1, other["primID"]))
        (ow, oc), (ew, ec) = ([statistics.median(r) for r in rates[k]] for k in ("ours", "embreex"))
        print(f"| {label} ({len(rays):,}) | {ow:.1f} Mrays/s | {ew:.1f} Mrays/s | {ow / ew:.2f}x "
              f"| {oc:.1f} Mrays/CPU-s | {ec:.1f} Mrays/CPU-s | {oc / ec:.2f}x | {same:.4%} |")


if __name__ == "__main__":
    sys.exit(main())
