"""Frames per second of raytracer.distributed.render_many on a local Dask cluster of two
worker processes (one thread each) against two local processes (one rendering thread
each) rendering half the frames each: the same frames (colour, depth, normal, object
ids), the same cameras on a ring, the scene read once per process either way.

    python3 bench/render_many.py --frames 60 --size 128 [--scene bench/dragon.toml]
"""

import argparse
import math
import multiprocessing
import os
import time

import numpy as np

AOVS = ["depth", "normal", "object_id"]


def cameras(frames, look_to, radius):
    out = []
    for k in range(frames):
        a = 2 * math.pi * k / frames
        eye = (look_to[0] + radius * math.sin(a), look_to[1] + 0.3 * radius, look_to[2] + radius * math.cos(a))
        out.append(dict(look_from=eye, look_to=tuple(look_to)))
    return out


def half(args):
    scene_path, cams, common = args
    os.environ["RAYON_NUM_THREADS"] = "1"
    import raytracer

    scene = raytracer.Scene(scene_path)
    for camera in cams:
        scene.render(aovs=AOVS, **common, **camera)
    return len(cams)


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--scene", default=os.path.join(os.path.dirname(__file__), "..", "examples", "cornell-box", "scene.obj"))
    p.add_argument("--frames", type=int, default=60)
    p.add_argument("--size", type=int, default=128)
    p.add_argument("--spp", type=int, default=1)
    args = p.parse_args()
    os.environ["RAYON_NUM_THREADS"] = "1"  # inherited by the workers and the processes
    import raytracer
    import raytracer.distributed
    from dask.distributed import Client, LocalCluster

    framed = raytracer.Scene(args.scene).options()
    radius = float(np.linalg.norm(np.subtract(framed["look_from"], framed["look_to"])))
    cams = cameras(args.frames, framed["look_to"], radius)
    common = dict(width=args.size, height=args.size, spp=args.spp)

    started = time.perf_counter()
    with multiprocessing.get_context("spawn").Pool(2) as pool:
        done = sum(pool.map(half, [(args.scene, cams[0::2], common), (args.scene, cams[1::2], common)]))
    local = time.perf_counter() - started
    assert done == args.frames

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=":0") as cluster, Client(cluster) as client:
        client.wait_for_workers(2)
        started = time.perf_counter()
        count = sum(1 for _ in raytracer.distributed.render_many(args.scene, cams, client, aovs=AOVS, **common))
        dask = time.perf_counter() - started
        loads = sum(client.run(lambda: raytracer.distributed._loads).values())
    assert count == args.frames
    print(f"{args.frames} frames {args.size}x{args.size} spp {args.spp} (colour, depth, normal, ids) of {os.path.basename(args.scene)}")
    print(f"two local processes: {local:.2f} s ({args.frames / local:.1f} frames/s)")
    print(f"render_many, 2 Dask workers: {dask:.2f} s ({args.frames / dask:.1f} frames/s; scene read {loads} times)")
    print(f"Dask / local time: {dask / local:.2f}")


if __name__ == "__main__":
    main()
