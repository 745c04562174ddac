"""Frames per second of raytracer.distributed.render_many on a local Dask cluster of two
worker processes (one thread each) against two local processes (a multiprocessing pool,
one rendering thread each) doing the same work: the same frames (colour, depth,
normal, object ids), the same cameras on a ring, in the same chunks of consecutive
frames, the scene read once per process either way. Two modes, each against its own
baseline:

- ``client``: the frames' arrays reach this process (render_many's default; the pool's
  processes send theirs through their pipes);
- ``drop``: the baseline of earlier figures: the pool's processes drop their frames
  (return only their count) while render_many's frames reach this process as in
  ``client``: what delivering them costs Dask, above rendering alone;
- ``write``: the workers write each frame's files themselves (render_many's
  ``output_dir=``; the pool's processes call the same raytracer.dataset.write_frame)
  into a folder under --out, emptied before each run, and only small records reach
  this process.

    python3 bench/render_many.py --frames 60 --size 128 [--scene bench/dragon.toml] [--repeat 3] [--modes drop,client,write] [--nanny-malloc]
"""

import argparse
import math
import multiprocessing
import os
import resource
import shutil
import statistics
import tempfile
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


_scene = None


def start():
    """The pool's initializer: what a Dask worker has done before a render_many
    (Python started, the package imported); the scene is read by the first chunk."""
    os.environ["RAYON_NUM_THREADS"] = "1"
    import raytracer.dataset  # noqa: F401


def ready(_):
    """Holds a process of the pool long enough for the other to take the second."""
    time.sleep(0.3)


def chunk(args):
    """Renders a chunk of consecutive frames in a pool's process: their arrays back to
    the parent, or (with a folder) each frame written there and its record back."""
    first, cams, common, folder, drop, scene_path = args
    global _scene
    import raytracer
    from raytracer.dataset import write_frame

    if _scene is None:
        _scene = raytracer.Scene(scene_path)

    out = []
    for index, camera in enumerate(cams, first):
        frame = _scene.render(aovs=AOVS, **common, **camera)
        out.append(write_frame(_scene, index, frame, folder, **common, **camera) if folder else frame)
    # The parent counts the frames (a list's length, or the number itself).
    return len(out) if drop else out


def process_cpu(_):
    """The CPU time of a pool's process so far (user and system)."""
    time.sleep(0.3)  # so that each process takes one
    return cpu_seconds(resource.getrusage(resource.RUSAGE_SELF))


def keep_nanny_malloc():
    """Run on the workers with --nanny-malloc: render_many's frames then render under
    the nanny's MALLOC_TRIM_THRESHOLD_ (raytracer.distributed._recycled_pages finds no
    glibc)."""
    import raytracer.distributed

    raytracer.distributed._libc = False


def cpu_seconds(usage) -> float:
    return usage.ru_utime + usage.ru_stime


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--scene", default=os.path.join(os.path.dirname(__file__), "..", "examples", "cornell-box", "scene.obj"))
    p.add_argument("--frames", type=int, default=60)
    p.add_argument("--size", type=int, default=128)
    p.add_argument("--spp", type=int, default=1)
    p.add_argument("--repeat", type=int, default=3, help="rounds of runs (each mode local, then Dask)")
    p.add_argument("--modes", default="client,write")
    p.add_argument("--nanny-malloc", action="store_true", help="workers keep the nanny's malloc settings while rendering (render_many lifts them)")
    p.add_argument("--out", default=os.path.join(os.path.dirname(__file__), "work"), help="where the write mode's frames go")
    args = p.parse_args()
    modes = args.modes.split(",")
    os.environ["RAYON_NUM_THREADS"] = "1"  # inherited by the workers and the processes
    import raytracer
    import raytracer.distributed
    from dask.distributed import Client, LocalCluster

    framed = raytracer.Scene(args.scene).options()
    radius = float(np.linalg.norm(np.subtract(framed["look_from"], framed["look_to"])))
    cams = cameras(args.frames, framed["look_to"], radius)
    common = dict(width=args.size, height=args.size, spp=args.spp)
    os.makedirs(args.out, exist_ok=True)
    folder = tempfile.mkdtemp(prefix="render-many-", dir=args.out)

    # Local and Dask runs in turn, the ratio taken pair by pair: a machine whose speed
    # drifts (other people's builds) moves both of a pair alike. Each run reads the
    # scene once per process: the workers forget it before each Dask run.
    results = {mode: {"local": [], "dask": [], "local_cpu": [], "dask_cpu": [], "ratio": [], "cpu_ratio": []} for mode in modes}
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=":0") as cluster, Client(cluster) as client:
        client.wait_for_workers(2)
        if args.nanny_malloc:
            client.run(keep_nanny_malloc)
        # The chunks render_many makes of these frames, for the pool too.
        per_task = raytracer.distributed._frames_per_task(client, [dict(common, **c) for c in cams])
        for _ in range(args.repeat):
            for mode in modes:
                out = folder if mode == "write" else None
                drop = mode == "drop"

                def empty():
                    shutil.rmtree(folder, ignore_errors=True)
                    os.makedirs(folder)

                empty()
                before_pool = cpu_seconds(resource.getrusage(resource.RUSAGE_CHILDREN))
                with multiprocessing.get_context("spawn").Pool(2, initializer=start) as pool:
                    # Both processes started and the package imported, as Dask's
                    # workers are before render_many: only what follows is counted
                    # (the pool's CPU time: its processes' total, less what they
                    # used so far).
                    pool.map(ready, [0, 0], chunksize=1)
                    children = sum(pool.map(process_cpu, [0, 0], chunksize=1))
                    own = time.process_time()
                    started = time.perf_counter()
                    work = [(i, cams[i : i + per_task], common, out, drop, args.scene) for i in range(0, len(cams), per_task)]
                    done = sum(n if isinstance(n, int) else len(n) for n in pool.imap_unordered(chunk, work))
                    pool.close()
                    pool.join()
                local = time.perf_counter() - started
                parent = time.process_time() - own
                pool_cpu = cpu_seconds(resource.getrusage(resource.RUSAGE_CHILDREN)) - before_pool - children
                local_cpu = pool_cpu + parent
                assert done == args.frames
                if out:
                    assert len(os.listdir(folder)) == args.frames * (len(AOVS) + 2)
                empty()
                raytracer.distributed.forget(client)
                loads = sum(client.run(lambda: raytracer.distributed._loads).values())
                workers_before = sum(client.run(time.process_time).values())
                own = time.process_time()
                started = time.perf_counter()
                frames = raytracer.distributed.render_many(args.scene, cams, client, aovs=AOVS, output_dir=out, **common)
                count = sum(1 for _ in frames)
                dask = time.perf_counter() - started
                # The workers' and this process's (the client's and the local cluster's scheduler's).
                own = time.process_time() - own
                workers = sum(client.run(time.process_time).values()) - workers_before
                dask_cpu = workers + own
                loads = sum(client.run(lambda: raytracer.distributed._loads).values()) - loads
                assert count == args.frames
                if out:
                    assert len(os.listdir(folder)) == args.frames * (len(AOVS) + 2)
                r = results[mode]
                for name, value in [("local", local), ("dask", dask), ("local_cpu", local_cpu), ("dask_cpu", dask_cpu), ("ratio", dask / local), ("cpu_ratio", dask_cpu / local_cpu)]:
                    r[name].append(value)
                print(
                    f"{mode}: local {local:.2f} s ({local_cpu:.2f} s CPU: pool {pool_cpu:.2f}, parent {parent:.2f}), render_many {dask:.2f} s ({dask_cpu:.2f} s CPU: workers {workers:.2f}, client's process {own:.2f}; "
                    f"scene read {loads} times): {dask / local:.2f} ({dask_cpu / local_cpu:.2f} in CPU), load {os.getloadavg()[0]:.1f}",
                    flush=True,
                )
    shutil.rmtree(folder, ignore_errors=True)
    print(f"{args.frames} frames {args.size}x{args.size} spp {args.spp} (colour, depth, normal, ids) of {os.path.basename(args.scene)}, {per_task} frames a task, medians of {args.repeat}")
    for mode, r in results.items():
        m = {name: statistics.median(values) for name, values in r.items()}
        print(f"{mode}: two local processes {m['local']:.2f} s ({args.frames / m['local']:.1f} frames/s, {m['local_cpu']:.2f} s CPU); "
              f"render_many {m['dask']:.2f} s ({args.frames / m['dask']:.1f} frames/s, {m['dask_cpu']:.2f} s CPU); "
              f"Dask / local, pair by pair: {m['ratio']:.2f} in time (pairs {', '.join(f'{v:.2f}' for v in r['ratio'])}), "
              f"{m['cpu_ratio']:.2f} in CPU ({', '.join(f'{v:.2f}' for v in r['cpu_ratio'])})")


if __name__ == "__main__":
    main()
