"""Frames per second of raytracer.distributed.render_many on a local Dask cluster of two
worker processes (one thread each) against two local processes (one rendering thread
each) rendering half the frames each: the same frames (colour, depth, normal, object
ids), the same cameras on a ring, the scene read once per process either way.

    python3 bench/render_many.py --frames 60 --size 128 [--scene bench/dragon.toml] [--repeat 3]
"""

import argparse
import math
import multiprocessing
import os
import resource
import statistics
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


def cpu_seconds(usage) -> float:
    return usage.ru_utime + usage.ru_stime


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--scene", default=os.path.join(os.path.dirname(__file__), "..", "examples", "cornell-box", "scene.obj"))
    p.add_argument("--frames", type=int, default=60)
    p.add_argument("--size", type=int, default=128)
    p.add_argument("--spp", type=int, default=1)
    p.add_argument("--repeat", type=int, default=3, help="pairs of runs (local, then Dask)")
    args = p.parse_args()
    os.environ["RAYON_NUM_THREADS"] = "1"  # inherited by the workers and the processes
    import raytracer
    import raytracer.distributed
    from dask.distributed import Client, LocalCluster

    framed = raytracer.Scene(args.scene).options()
    radius = float(np.linalg.norm(np.subtract(framed["look_from"], framed["look_to"])))
    cams = cameras(args.frames, framed["look_to"], radius)
    common = dict(width=args.size, height=args.size, spp=args.spp)

    # Local and Dask runs in turn, the ratio taken pair by pair: a machine whose speed
    # drifts (other people's builds) moves both of a pair alike. Each run reads the
    # scene once per process: the workers forget it before each Dask run.
    locals_, dasks, ratios, cpu_ratios = [], [], [], []
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=":0") as cluster, Client(cluster) as client:
        client.wait_for_workers(2)
        for _ in range(args.repeat):
            children = resource.getrusage(resource.RUSAGE_CHILDREN)
            started = time.perf_counter()
            with multiprocessing.get_context("spawn").Pool(2) as pool:
                done = sum(pool.map(half, [(args.scene, cams[0::2], common), (args.scene, cams[1::2], common)]))
                pool.close()
                pool.join()
            local = time.perf_counter() - started
            local_cpu = cpu_seconds(resource.getrusage(resource.RUSAGE_CHILDREN)) - cpu_seconds(children)
            assert done == args.frames
            raytracer.distributed.forget(client)
            loads = sum(client.run(lambda: raytracer.distributed._loads).values())
            before = sum(client.run(time.process_time).values()) + time.process_time()
            started = time.perf_counter()
            count = sum(1 for _ in raytracer.distributed.render_many(args.scene, cams, client, aovs=AOVS, **common))
            dask = time.perf_counter() - started
            # The workers' and this process's (the client's and the local cluster's scheduler's).
            dask_cpu = sum(client.run(time.process_time).values()) + time.process_time() - before
            loads = sum(client.run(lambda: raytracer.distributed._loads).values()) - loads
            assert count == args.frames
            locals_.append(local)
            dasks.append(dask)
            ratios.append(dask / local)
            cpu_ratios.append(dask_cpu / local_cpu)
            print(
                f"local {local:.2f} s ({local_cpu:.2f} s CPU), render_many {dask:.2f} s ({dask_cpu:.2f} s CPU; "
                f"scene read {loads} times): {dask / local:.2f} ({dask_cpu / local_cpu:.2f} in CPU)",
                flush=True,
            )
    local, dask, ratio, cpu_ratio = (statistics.median(v) for v in (locals_, dasks, ratios, cpu_ratios))
    print(f"{args.frames} frames {args.size}x{args.size} spp {args.spp} (colour, depth, normal, ids) of {os.path.basename(args.scene)}, medians of {args.repeat}")
    print(f"two local processes: {local:.2f} s ({args.frames / local:.1f} frames/s)")
    print(f"render_many, 2 Dask workers: {dask:.2f} s ({args.frames / dask:.1f} frames/s)")
    print(f"Dask / local time, pair by pair: {ratio:.2f}; CPU time (all processes): {cpu_ratio:.2f}")

if __name__ == "__main__":
    main()
