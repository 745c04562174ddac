"""What every peer script shares: the scene constants of bench/README.md, the
camera of SPEC.md, command-line handling and JSON output.

Standard library only, so that a peer whose package is missing can still report
that it skipped.
"""

from __future__ import annotations

import argparse
import json
import math
import resource
import statistics
import sys
import time

# The scene of bench/README.md.
LOOK_FROM = (0.09, 0.21, 0.27)
LOOK_TO = (-0.005, 0.12, -0.005)
FOV_DEGREES = 45.0
WIDTH, HEIGHT = 1024, 768
FLOOR_Y = 0.0525
# (position, intensity) of the key and fill lights.
LIGHTS = [((0.5, 0.9, 0.6), (1.0, 1.0, 1.0)), ((-0.6, 0.5, 0.5), (0.3, 0.3, 0.3))]
DRAGON = {"Ka": (0.01,) * 3, "Kd": (0.8, 0.2, 0.2), "Ks": (0.3,) * 3, "Ns": 64.0}
FLOOR = {"Ka": (0.01,) * 3, "Kd": (0.6, 0.6, 0.6), "Ks": (0.0,) * 3, "Ns": 1.0}
# Our renderer's spawn offset (src/scene/mod.rs SPAWN_OFFSET), scaled by max(|p|, 1).
SPAWN_OFFSET = 1e-4


def parse_args(description: str) -> argparse.Namespace:
    """The flags every peer takes."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--obj", required=True, help="the benchmark scene (.obj)")
    parser.add_argument("--ply", help="the dragon as an uncompressed PLY (Mitsuba)")
    parser.add_argument("--out", help="where to write the rendered image, if any")
    parser.add_argument("--repeat", type=int, default=3, help="runs per figure (median)")
    args = parser.parse_args()
    if args.repeat < 1:
        parser.error("--repeat must be at least 1")
    return args


def emit(result: dict) -> None:
    """Prints the one JSON object a peer reports, with its peak RSS."""
    result["peak_rss_mb"] = round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)
    print(json.dumps(result))
    sys.stdout.flush()


def skip(peer: str, reason: str) -> None:
    """Reports that `peer` cannot run here, and why, then exits cleanly."""
    print(json.dumps({"peer": peer, "skipped": reason}))
    sys.exit(0)


def timed(fn, repeat: int):
    """Runs `fn` `repeat` times; returns (median milliseconds, all ms, last result)."""
    times, result = [], None
    for _ in range(repeat):
        start = time.perf_counter()
        result = fn()
        times.append((time.perf_counter() - start) * 1000.0)
    return statistics.median(times), times, result


def camera_basis():
    """(origin, right, up, backward) of SPEC.md's LookAt camera with world up +y."""

    def sub(a, b):
        return tuple(x - y for x, y in zip(a, b))

    def cross(a, b):
        return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])

    def normalize(a):
        n = math.sqrt(sum(x * x for x in a))
        return tuple(x / n for x in a)

    backward = normalize(sub(LOOK_FROM, LOOK_TO))
    right = cross((0.0, 1.0, 0.0), backward)
    right = normalize(right) if any(abs(c) > 1e-12 for c in right) else (1.0, 0.0, 0.0)
    up = cross(backward, right)
    return LOOK_FROM, right, up, backward


def ms(value: float) -> float:
    """Milliseconds rounded for the report."""
    return round(value, 2)
