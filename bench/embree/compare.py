#!/usr/bin/env python3
"""Ours against Embree 3 on the same rays, in one run: `raytracer bench` and
`bench/embree/embree_bench` alternate RUNS times (each run itself a median of
--repeat; who goes first alternates too), and the medians of the runs are printed side
by side as a markdown table, with the median and range of the runs' pairwise ratios.

    python3 bench/embree/compare.py [--runs 3] [--repeat 3] [--threads 2] [SCENE]

SCENE defaults to bench/work/dragon-full.obj with the camera of bench/README.md.
With --instances (issue 39's field of dragons), Embree builds the scene's own
triangles (the floor) beside one RTC_GEOMETRY_TYPE_INSTANCE per matrix of the .npy
file over the mesh of --mesh, built once (its MESH.bin written by
bench/embree/write_mesh.py into bench/work/), which SCENE places the same way:

    python3 bench/instancing/make_field.py
    python3 bench/embree/compare.py bench/work/field.toml --instances bench/work/field.npy \
        --mesh bench/work/package/models/dragon_vrip.ply.gz
Needs target/release/raytracer (cargo build --release) and libembree-dev; builds
bench/work/embree_bench with bench/embree/build.sh when it is missing or older than its
source. The rays are written once by `raytracer bench --dump-rays` and read by both.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
CAMERA = [
    "--width", "1024", "--height", "768", "--fov", "45",
    "--look-from", "0.09,0.21,0.27", "--look-to=-0.005,0.12,-0.005", "--depth", "8",
]
# (label, our key, Embree's key, unit); rates are per second of wall time and of CPU
# time (all threads), the second steadier on a shared machine.
ROWS = [
    ("BVH build (wall)", "build_ms", "build_ms", "ms"),
    ("BVH build (CPU)", "build_cpu_ms", "build_cpu_ms", "ms"),
]
for kind, label in [
    ("primary", "primary rays, single"),
    ("primary_packet", "primary rays, 4x4 packets"),
    ("shadow", "shadow rays, single"),
    ("shadow_packet", "shadow rays, 4x4 packets"),
    ("incoherent", "incoherent rays, single"),
    ("occlusion", "occlusion rays (the incoherent rays, any hit, no limit), single"),
]:
    ROWS.append((f"{label} (wall)", f"{kind}_mrays_per_s", f"{kind}_mrays_per_s", "Mrays/s"))
    ROWS.append((f"{label} (CPU)", f"{kind}_mrays_per_cpu_s", f"{kind}_mrays_per_cpu_s", "Mrays/CPU-s"))
# Our array queries (`Scene::intersect_primitives`, `Scene::occluded_rays`: runs of
# coherent rays as packets, others several in flight in scenes larger than the
# last-level cache, else ray by ray) on the same rays, against Embree's single rays.
for kind in ("primary", "shadow", "incoherent", "occlusion"):
    for unit_key, unit in [("mrays_per_s", "wall"), ("mrays_per_cpu_s", "CPU")]:
        ROWS.append((f"{kind} rays, our array query / Embree single ({unit})",
                     f"{kind}_stream_{unit_key}", f"{kind}_{unit_key}",
                     "Mrays/s" if unit == "wall" else "Mrays/CPU-s"))
# The same arrays, 256 rays a call, against Embree's stream calls (rtcIntersect1M,
# rtcOccluded1M; coherent for camera and shadow rays).
for kind in ("primary", "shadow", "incoherent", "occlusion"):
    for unit_key, unit in [("mrays_per_s", "wall"), ("mrays_per_cpu_s", "CPU")]:
        ROWS.append((f"{kind} rays, our array query / Embree stream ({unit})",
                     f"{kind}_stream_{unit_key}", f"{kind}_stream_{unit_key}",
                     "Mrays/s" if unit == "wall" else "Mrays/CPU-s"))


def run_json(command: list[str]) -> dict:
    done = subprocess.run(command, check=True, capture_output=True, text=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", nargs="?", default=str(ROOT / "bench/work/dragon-full.obj"))
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--instances", help="(N, 4, 4) float32 .npy of the instances SCENE places")
    parser.add_argument("--mesh", help="the PLY mesh those instances place")
    parser.add_argument("--ours", help="our binary (default: target/release/raytracer; "
                        "give $CARGO_TARGET_DIR/release/raytracer for another target dir)")
    args = parser.parse_args()
    if bool(args.instances) != bool(args.mesh):
        parser.error("--instances and --mesh go together")
    ours_bin = Path(args.ours) if args.ours else ROOT / "target/release/raytracer"
    if not ours_bin.exists():
        sys.exit("compare.py: error: build target/release/raytracer first (cargo build --release)")
    embree_bin = ROOT / "bench/work/embree_bench"
    source = ROOT / "bench/embree/embree_bench.c"
    if not embree_bin.exists() or embree_bin.stat().st_mtime < source.stat().st_mtime:
        subprocess.run([str(ROOT / "bench/embree/build.sh"), str(embree_bin)], check=True)
    rays = ROOT / "bench/work/rays.bin"
    ours_cmd = [str(ours_bin), "bench", args.scene, *CAMERA, "--threads", str(args.threads),
                "--repeat", str(args.repeat)]
    embree_cmd = [str(embree_bin), str(rays), "--repeat", str(args.repeat),
                  "--threads", str(args.threads)]
    if args.instances:
        mesh_bin = ROOT / "bench/work/mesh.bin"
        subprocess.run([sys.executable, str(ROOT / "bench/embree/write_mesh.py"), args.mesh,
                        str(mesh_bin)], check=True)
        embree_cmd += ["--mesh", str(mesh_bin), "--instances", args.instances]
    run_json(ours_cmd[:2] + ours_cmd[2:] + ["--dump-rays", str(rays)])
    ours, theirs = [], []
    for run in range(args.runs):
        # Who goes first alternates, so that a drift in the machine's speed does not
        # always favour the same side.
        if run % 2 == 0:
            ours.append(run_json(ours_cmd))
            theirs.append(run_json(embree_cmd))
        else:
            theirs.append(run_json(embree_cmd))
            ours.append(run_json(ours_cmd))
    for key, their_keys in [
        ("primary_hits", ("primary_hits", "primary_stream_hits")),
        ("shadow_occluded", ("shadow_occluded", "shadow_stream_occluded")),
        ("incoherent_hits", ("incoherent_hits", "incoherent_stream_hits")),
        ("occlusion_blocked", ("occlusion_blocked", "occlusion_stream_blocked")),
    ]:
        for their_key in their_keys:
            a, b = ours[0][key], theirs[0][their_key]
            if a != b:
                print(f"warning: {key}: ours {a}, Embree's {their_key} {b}", file=sys.stderr)
    med = lambda runs, key: statistics.median(r[key] for r in runs)  # noqa: E731
    load = os.getloadavg()[0]
    print(f"{args.runs} alternating runs, each a median of {args.repeat}; {args.threads} threads; "
          f"load average {load:.1f} at the end; {theirs[0]['version']}")
    print()
    print("| figure | ours | Embree | ours faster by | pair by pair |")
    print("|---|---|---|---|---|")
    for label, ours_key, their_key, unit in ROWS:
        a, b = med(ours, ours_key), med(theirs, their_key)
        # Above 1: ours faster (Embree / ours for times, ours / Embree for rates).
        faster = (lambda o, t: t / o) if unit == "ms" else (lambda o, t: o / t)
        # Each run's ratio against the run beside it: their median and range hold
        # when the machine's speed drifts between runs, as medians of each side alone
        # do not.
        pairs = [faster(o[ours_key], t[their_key]) for o, t in zip(ours, theirs)]
        print(f"| {label} | {a:.1f} {unit} | {b:.1f} {unit} | {statistics.median(pairs):.2f}x | "
              f"{min(pairs):.2f}-{max(pairs):.2f} |")
    print()
    print(f"same work: primary hits {ours[0]['primary_hits']:,} (Embree {theirs[0]['primary_hits']:,}), "
          f"shadow rays blocked {ours[0]['shadow_occluded']:,} (Embree {theirs[0]['shadow_occluded']:,}), "
          f"incoherent hits {ours[0]['incoherent_hits']:,} (Embree {theirs[0]['incoherent_hits']:,}), "
          f"occlusion rays blocked {ours[0]['occlusion_blocked']:,} "
          f"(Embree {theirs[0]['occlusion_blocked']:,}); "
          f"our SAH cost {ours[0]['sah_cost']} (binary), {ours[0]['wide_sah_cost']} (8-wide)")
    print(json.dumps({"ours": ours, "embree": theirs}), file=sys.stderr)


if __name__ == "__main__":
    main()
