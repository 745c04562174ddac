"""Page faults and CPU of the workers of a local Dask cluster (two processes, one thread
each) while render_many writes 300 frames of 256x256 of the dragon (colour, depth,
normal, ids; scene already read), against a pool of two processes writing the same:
what Dask's nanny's MALLOC_TRIM_THRESHOLD_ costs, and what render_many's lifting it
(raytracer.distributed._recycled_pages) saves. BENCHMARKS.md's render_many section.

    python3 bench/render_many_faults.py [--no-nanny-env] [--no-lift] [--scene PATH]
"""

import argparse
import math
import multiprocessing
import os
import resource
import shutil
import tempfile

import numpy as np

AOVS = ["depth", "normal", "object_id"]
SIZE = dict(width=256, height=256)


def usage():
    u = resource.getrusage(resource.RUSAGE_SELF)
    return (u.ru_utime, u.ru_stime, u.ru_minflt)


def local(args):
    scene_path, cameras, out = args
    os.environ["RAYON_NUM_THREADS"] = "1"
    import raytracer
    from raytracer.dataset import write_frame

    scene = raytracer.Scene(scene_path)
    scene.render(width=8, height=8)
    before = usage()
    for i, camera in enumerate(cameras):
        frame = scene.render(aovs=AOVS, **SIZE, **camera)
        write_frame(scene, i, frame, out, **SIZE, **camera)
    return [a - b for a, b in zip(usage(), before)]


def no_lift():
    import raytracer.distributed

    raytracer.distributed._libc = False


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--scene", default="bench/work/package/models/dragon_vrip_res2.ply.gz")
    p.add_argument("--no-nanny-env", action="store_true", help="the nanny sets no MALLOC_TRIM_THRESHOLD_")
    p.add_argument("--no-lift", action="store_true", help="render_many keeps the nanny's malloc settings")
    args = p.parse_args()
    os.environ["RAYON_NUM_THREADS"] = "1"
    import dask
    import raytracer
    import raytracer.distributed as rd
    from dask.distributed import Client, LocalCluster

    if args.no_nanny_env:
        dask.config.set({"distributed.nanny.pre-spawn-environ": {}})
    framed = raytracer.Scene(args.scene).options()
    look_to = framed["look_to"]
    r = float(np.linalg.norm(np.subtract(framed["look_from"], look_to)))
    cameras = [
        dict(look_from=(look_to[0] + r * math.sin(a), look_to[1] + 0.3 * r, look_to[2] + r * math.cos(a)), look_to=tuple(look_to))
        for a in (2 * math.pi * k / 300 for k in range(300))
    ]
    out = tempfile.mkdtemp(dir=os.path.dirname(os.path.abspath(__file__)))
    with multiprocessing.get_context("spawn").Pool(2) as pool:
        for u in pool.map(local, [(args.scene, cameras[0::2], out), (args.scene, cameras[1::2], out)]):
            print(f"pool process: {u[0]:.2f} s user, {u[1]:.2f} s system, {u[2]} page faults")
    with LocalCluster(n_workers=2, threads_per_worker=1, host="127.0.0.1", dashboard_address=":0") as cluster, Client(cluster) as client:
        if args.no_lift:
            client.run(no_lift)
        # The scene read and kept by both workers first, as the pool's processes do.
        list(rd.render_many(args.scene, cameras[:4], client, aovs=AOVS, output_dir=out, frames_per_task=2, **SIZE))
        before = client.run(usage)
        list(rd.render_many(args.scene, cameras, client, aovs=AOVS, output_dir=out, **SIZE))
        after = client.run(usage)
        for worker in after:
            u = [a - b for a, b in zip(after[worker], before[worker])]
            print(f"Dask worker: {u[0]:.2f} s user, {u[1]:.2f} s system, {u[2]} page faults")
    shutil.rmtree(out)


if __name__ == "__main__":
    main()
