#!/usr/bin/env python3
"""Every stage of the whole process, from `raytracer render --stats`: wall time, CPU
time (all threads) and page faults of the parse, the BVH build and its three steps,
the render, post-processing, PNG encoding and the file write, as medians over RUNS
renders of SCENE, printed as a markdown table.

    python3 bench/stages.py [--runs 11] [--pause 0] [--binary target/release/raytracer] [SCENE]

SCENE defaults to bench/work/dragon-full.obj with the camera of bench/README.md.
`--pause S` sleeps S seconds before each render: on the virtual machines measured,
memory left free for a few seconds is taken back by the host and costs more to touch
again, so back to back (0) and after a pause (5) are both worth a look.
"""

from __future__ import annotations

import argparse
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CAMERA = [
    "--width", "1024", "--height", "768", "--fov", "45",
    "--look-from", "0.09,0.21,0.27", "--look-to=-0.005,0.12,-0.005", "--depth", "8",
]
# `name  <wall> ms  <cpu> ms CPU  <faults> faults ...`
STAGE = re.compile(r"\s*(\S.*?)\s{2,}([\d.]+) ms\s+([\d.]+) ms CPU\s+(\d+) faults")
PEAK = re.compile(r"peak memory\s+([\d.]+) MB")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", nargs="?", default=str(ROOT / "bench/work/dragon-full.obj"))
    parser.add_argument("--runs", type=int, default=11)
    parser.add_argument("--pause", type=float, default=0.0)
    parser.add_argument("--binary", default=str(ROOT / "target/release/raytracer"))
    args = parser.parse_args()

    stages: dict[str, list[tuple[float, float, int]]] = {}
    peaks: list[float] = []
    with tempfile.TemporaryDirectory() as out_dir:
        out = str(Path(out_dir) / "stages.png")
        for _ in range(args.runs):
            if args.pause:
                time.sleep(args.pause)
            command = [args.binary, "render", args.scene, *CAMERA, "-o", out, "--stats"]
            result = subprocess.run(command, capture_output=True, text=True)
            if result.returncode != 0:
                sys.stderr.write(result.stderr)
                return result.returncode
            for line in result.stderr.splitlines():
                if match := STAGE.match(line):
                    name, wall, cpu, faults = match.groups()
                    stages.setdefault(name, []).append((float(wall), float(cpu), int(faults)))
                elif match := PEAK.match(line):
                    peaks.append(float(match.group(1)))
    if not stages:
        sys.stderr.write("no stage with CPU time in --stats: this OS reports none\n")
        return 1

    print(f"{args.runs} renders, medians, {args.pause:g} s apart\n")
    print("| stage | wall | CPU | page faults |\n|---|---|---|---|")
    for name, values in stages.items():
        wall, cpu, faults = (statistics.median(column) for column in zip(*values))
        print(f"| {name} | {wall:.1f} ms | {cpu:.1f} ms | {faults:,.0f} |")
    if peaks:
        print(f"\npeak memory {statistics.median(peaks):.1f} MB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
