"""Writes a small BlenderProc-style dataset of a scene: for each camera on a ring
around it, the colour (PNG), depth (float32 .npy, z-depth along the optical axis, inf
on a miss), normals (world space, .npy), segmentation (object ids, int32 .npy, -1 on a
miss) and its pose (a JSON file per frame: OpenGL and OpenCV conventions,
intrinsics), then `cameras.json` with every pose and the objects' names. The frames
are rendered and written by the workers of a local Dask cluster
(`render_many(..., output_dir=...)`: only the small records come back), or by this
process with --local; either way by `raytracer.dataset.write_frame`, so the files are
the same.

    python3 examples/dataset.py examples/cornell-box/scene.obj out/ --frames 8 --size 128
"""

import argparse
import json
import math
import os

import numpy as np

import raytracer
import raytracer.distributed
from raytracer.dataset import write_frame


def ring(centre, radius, height, frames):
    """Camera-to-world matrices (OpenGL) on a ring around `centre`, looking at it."""
    poses = []
    for k in range(frames):
        angle = 2 * math.pi * k / frames
        eye = np.array(centre) + [radius * math.sin(angle), height, radius * math.cos(angle)]
        back = eye - centre
        back /= np.linalg.norm(back)
        right = np.cross([0.0, 1.0, 0.0], back)
        right /= np.linalg.norm(right)
        up = np.cross(back, right)
        pose = np.eye(4)
        pose[:3, 0], pose[:3, 1], pose[:3, 2], pose[:3, 3] = right, up, back, eye
        poses.append(pose)
    return poses


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scene")
    p.add_argument("out")
    p.add_argument("--frames", type=int, default=8)
    p.add_argument("--size", type=int, default=128)
    p.add_argument("--spp", type=int, default=4)
    p.add_argument("--local", action="store_true", help="render in this process, without Dask")
    args = p.parse_args()
    os.makedirs(args.out, exist_ok=True)
    scene = raytracer.Scene(args.scene)
    framed = scene.options()
    centre = np.array(framed["look_to"])
    radius = float(np.linalg.norm(np.array(framed["look_from"]) - centre))
    poses = ring(centre, radius, radius * 0.3, args.frames)
    f = args.size / (2 * math.tan(math.radians(40) / 2))
    intrinsics = (f, f, (args.size - 1) / 2, (args.size - 1) / 2)
    cameras = [dict(camera_to_world=pose, intrinsics=intrinsics) for pose in poses]
    common = dict(width=args.size, height=args.size, spp=args.spp)
    aovs = ["depth", "normal", "object_id"]
    if args.local:
        records = (
            (i, write_frame(scene, i, raytracer.render(scene, aovs=aovs, **common, **camera), args.out, **common, **camera))
            for i, camera in enumerate(cameras)
        )
        client = None
    else:
        from dask.distributed import Client, LocalCluster

        client = Client(LocalCluster(n_workers=2, threads_per_worker=1, host="127.0.0.1", dashboard_address=":0"))
        # Each worker writes its frames into args.out; what comes back is the record.
        records = raytracer.distributed.render_many(args.scene, cameras, client, aovs=aovs, output_dir=args.out, **common)
    poses = {}
    for i, record in records:
        poses[i] = {"frame": i, **record["pose"]}
        print(f"frame {i} written: {', '.join(os.path.basename(path) for path in record['files'].values())}")
    with open(os.path.join(args.out, "cameras.json"), "w") as f:
        json.dump({"objects": scene.object_names, "frames": [poses[i] for i in sorted(poses)]}, f, indent=1)
    if client is not None:
        client.close()

if __name__ == "__main__":
    main()
