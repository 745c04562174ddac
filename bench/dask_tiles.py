"""The README's figure: one large render on this machine, locally and on a local Dask
cluster of 1 and 2 worker processes, and what each tile costs in overhead.

    python3 bench/dask_tiles.py [--width 3840 --height 2160 --mode path --spp 2 --repeat 3]

Every worker process renders on one core (RAYON_NUM_THREADS=1) so that 1 and 2 workers
compare with local renders on 1 and 2 threads. Times are wall-clock seconds of the
render call alone (the cluster is started before): for a local render, reading the
scene and rendering; for a distributed one, also checking the scene files, reading
the scene on every worker, and moving the tiles. The overhead per tile is
(distributed on 1 worker - local on 1 thread) / tiles, which spreads the fixed cost of a
render over its tiles; the last line separates the two (the slope between the smallest
and the largest tiles). Every distributed image is
checked bit-identical to the local one. Each figure is the best of --repeat runs (the
machine is shared). Prints a Markdown table. A cheap render (`--mode depth --spp 1`)
shows the overhead alone.
"""

import argparse
import logging
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]

LOCAL = """
import sys, time, numpy, raytracer
options = eval(sys.argv[2])
start = time.perf_counter()
image = raytracer.render(sys.argv[1], **options)
print(time.perf_counter() - start)
numpy.save(sys.argv[3], image)
"""


def local(scene, options, threads, out):
    env = dict(os.environ, RAYON_NUM_THREADS=str(threads))
    result = subprocess.run(
        [sys.executable, "-c", LOCAL, str(scene), repr(options), out],
        env=env, capture_output=True, text=True, check=True,
    )
    return float(result.stdout)


def measure(scene, options, sizes, repeat, saturation):
    """Rows (render, tile, tiles, seconds, overhead per tile): the best of `repeat` runs
    of each, on this shared machine."""
    import dask
    from distributed import Client, LocalCluster
    import raytracer.distributed as rd

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        reference = os.path.join(tmp, "local.npy")
        base = {}
        for threads in (1, 2):
            base[threads] = min(local(scene, options, threads, reference) for _ in range(repeat))
            rows.append((f"local, {threads} thread{'s' if threads > 1 else ''}", "-", "-", base[threads], ""))
        expected = np.load(reference)
        for workers in (1, 2):
            with dask.config.set({"distributed.scheduler.worker-saturation": saturation}), LocalCluster(
                n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                dashboard_address="127.0.0.1:0", silence_logs=logging.ERROR,
                env={"RAYON_NUM_THREADS": "1"},
            ) as cluster, Client(cluster) as client:
                for size in sizes:
                    tiles = len(rd.tiles(options["width"], options["height"], size))
                    times = []
                    for _ in range(repeat):
                        start = time.perf_counter()
                        image = rd.render(scene, client, tile_size=size, **options)
                        times.append(time.perf_counter() - start)
                        assert np.array_equal(image.view(np.uint32), expected.view(np.uint32)), "not identical"
                    seconds = min(times)
                    overhead = f"{(seconds - base[1]) / tiles * 1e3:.2f} ms" if workers == 1 else ""
                    rows.append((f"Dask, {workers} worker{'s' if workers > 1 else ''}", size, tiles, seconds, overhead))
    return rows


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--scene", default=str(REPO / "examples/cornell-box/scene.toml"))
    p.add_argument("--width", type=int, default=3840)
    p.add_argument("--height", type=int, default=2160)
    p.add_argument("--mode", default="path")
    p.add_argument("--spp", type=int, default=2)
    p.add_argument("--tile-sizes", default="64,256")
    p.add_argument("--repeat", type=int, default=3, help="runs of each; the fastest is shown")
    p.add_argument("--saturation", type=float, default=float("inf"),
                   help="the scheduler's worker-saturation (Dask's default: 1.1); inf as "
                   "python -m raytracer.distributed sets it for its local cluster")
    args = p.parse_args()
    options = dict(width=args.width, height=args.height, mode=args.mode, spp=args.spp)
    sizes = [int(s) for s in args.tile_sizes.split(",")]
    rows = measure(args.scene, options, sizes, args.repeat, args.saturation)
    print(f"{args.width}x{args.height}, {args.mode} mode, {args.spp} spp, {Path(args.scene).name}, "
          f"worker-saturation {args.saturation}, best of {args.repeat}\n")
    print("| render | tile | tiles | seconds | overhead per tile |")
    print("|---|---|---|---|---|")
    for name, size, tiles, seconds, overhead in rows:
        size = f"{size}x{size}" if size != "-" else size
        print(f"| {name} | {size} | {tiles} | {seconds:.2f} | {overhead} |")
    # The cost of a tile, apart from the fixed cost of a render: the slope between the
    # smallest and the largest tiles on one worker.
    one = [(tiles, seconds) for name, _, tiles, seconds, _ in rows if name == "Dask, 1 worker"]
    if len(one) >= 2:
        (many, slow), (few, fast) = max(one), min(one)
        per_tile = (slow - fast) / (many - few)
        fixed = fast - few * per_tile - rows[0][3]
        print(f"\nOn 1 worker: {per_tile * 1e3:.2f} ms per tile and {fixed:.2f} s per render "
              "besides the local render's time.")


if __name__ == "__main__":
    main()
