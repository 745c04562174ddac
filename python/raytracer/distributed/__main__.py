"""``python -m raytracer.distributed SCENE -o OUT.png|OUT.exr [--scheduler ADDRESS]``

Renders a scene on a Dask cluster and writes the image as ``raytracer render`` does:
PNG post-processed, EXR linear, replaced atomically. Without ``--scheduler`` it starts
a local cluster on this machine, bound to 127.0.0.1. Errors print ``error: MESSAGE``
and exit with status 2; an interrupt (Ctrl-C, SIGTERM, SIGHUP) exits with 130 and
leaves the output as it was, unless the new image was already written (then it says
so and exits 0: an interrupt while the file is written waits for the write).
"""

from __future__ import annotations

import argparse
import logging
import os
import re
import signal
import sys
from typing import Optional, Sequence

import raytracer
import raytracer.distributed

#: Flags whose value is a vector: "--look-from -1,2,3" is passed as "--look-from=-1,2,3"
#: so that argparse does not take the value for a flag.
VECTOR_FLAGS = ("--look-from", "--look-to", "--up")

EXIT_ERROR = 2
EXIT_INTERRUPTED = 130


class Interrupted(BaseException):
    """SIGINT, SIGTERM or SIGHUP, raised like KeyboardInterrupt between two Python steps (so
    never in the middle of the library's atomic write)."""


def vector(text: str) -> "tuple[float, float, float]":
    """``X,Y,Z``: three numbers with commas and no spaces."""
    parts = text.split(",")
    if len(parts) != 3:
        raise argparse.ArgumentTypeError(
            f"a vector is written X,Y,Z, three numbers with commas and no spaces, not {text!r}"
        )
    try:
        return tuple(float(p) for p in parts)  # type: ignore[return-value]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not three numbers") from None


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m raytracer.distributed",
        description="Render a scene on a Dask cluster (as tiles) and write a PNG or OpenEXR image.",
        epilog="Camera and render flags are those of `raytracer render`: each one given "
        "overrides the TOML scene file's value, which overrides the default.",
    )
    p.add_argument("scene", metavar="SCENE", help="the scene: OBJ, PLY, glTF 2.0 or TOML, optionally gzip-compressed")
    p.add_argument(
        "-o", "--output", required=True, metavar="OUT.png|OUT.exr",
        help="the image, replaced atomically; .png is post-processed, .exr linear",
    )
    p.add_argument(
        "--scheduler", metavar="tcp://HOST:PORT",
        help="the Dask scheduler to use; without it, a local cluster on 127.0.0.1",
    )
    p.add_argument(
        "--workers", type=int, metavar="N",
        help="worker processes of the local cluster (default 2; not with --scheduler)",
    )
    p.add_argument(
        "-j", "--threads", type=int, metavar="N",
        help="render threads per local worker; 0 shares the cores among the workers (default)",
    )
    p.add_argument("--tile-size", type=int, default=64, metavar="PIXELS", help="side of the square tiles (default 64)")
    ship = p.add_mutually_exclusive_group()
    ship.add_argument("--ship", dest="ship", action="store_true", default=None,
                      help="send the scene's files to the workers")
    ship.add_argument("--no-ship", dest="ship", action="store_false",
                      help="the workers read the scene's path themselves (a shared file system)")
    p.add_argument("-q", "--quiet", action="store_true", help="print nothing but errors")
    view = p.add_argument_group("camera and render (as `raytracer render`)")
    view.add_argument("--width", type=int, metavar="PIXELS", help="image width [default: 640]")
    view.add_argument("--height", type=int, metavar="PIXELS", help="image height [default: 480]")
    view.add_argument("--fov", type=float, metavar="DEGREES", help="vertical field of view [default: 90]")
    view.add_argument("--look-from", type=vector, metavar="X,Y,Z", help="camera position [default: framed: the camera frames the scene]")
    view.add_argument("--look-to", type=vector, metavar="X,Y,Z", help="point looked at [default: framed; 0,0,-1 with --look-from alone]")
    view.add_argument("--up", type=vector, metavar="X,Y,Z", help="world up direction [default: 0,1,0]")
    view.add_argument("--depth", type=int, metavar="N", help="recursion depth [default: 4; 64 in path mode]")
    view.add_argument("--mode", metavar="MODE", help="full, depth, normal or path [default: full]")
    view.add_argument("--spp", type=int, metavar="N", help="samples per pixel [default: 1; 4 in full mode under the default light rig; 64 in path mode]")
    view.add_argument("--exposure", type=float, metavar="STOPS", help="path mode's exposure for PNG [default: 0]")
    view.add_argument("--seed", type=int, metavar="N", help="seed of the random numbers [default: 0]")
    view.add_argument(
        "--tonemap", metavar="OPERATOR",
        help="path mode's tone map for PNG: standard, khronos-neutral, agx or aces [default: khronos-neutral]",
    )
    view.add_argument(
        "--aperture-radius", type=float, metavar="R",
        help="radius of the camera's thin lens in scene units; 0 is a pinhole [default: 0]",
    )
    view.add_argument(
        "--focus-distance", type=float, metavar="D",
        help="distance to the plane in focus [default: the distance from --look-from to --look-to]",
    )
    return p


def joined_vectors(argv: Sequence[str]) -> "list[str]":
    """``--look-from -1,2,3`` as ``--look-from=-1,2,3``: argparse would take a value
    starting with ``-`` for a flag."""
    out: "list[str]" = []
    i = 0
    while i < len(argv):
        if argv[i] in VECTOR_FLAGS and i + 1 < len(argv) and argv[i + 1].startswith("-"):
            out.append(f"{argv[i]}={argv[i + 1]}")
            i += 2
        else:
            out.append(argv[i])
            i += 1
    return out


def as_flags(message: str) -> str:
    """A message of the package's, which names keywords (``invalid look_from: ...``),
    as ``raytracer render`` says it, naming flags (``invalid --look-from: ...``)."""
    if not message.startswith("invalid "):
        return message
    head, colon, rest = message.partition(": ")
    names = "|".join(sorted(raytracer.OPTIONS, key=len, reverse=True))
    head = re.sub(rf"\b({names})\b", lambda m: "--" + m.group(1).replace("_", "-"), head)
    return head + colon + rest


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Runs the command; returns the exit status."""
    args = parser().parse_args(joined_vectors(sys.argv[1:] if argv is None else argv))

    def interrupted(signum: int, frame: object) -> None:
        raise Interrupted()

    # SIGINT too, explicitly: a process started in the background inherits SIGINT
    # ignored, and Python then installs no KeyboardInterrupt handler of its own (the
    # `raytracer` binary's handler is installed the same way, whatever it inherits).
    for name in ("SIGINT", "SIGTERM", "SIGHUP"):
        if hasattr(signal, name):
            signal.signal(getattr(signal, name), interrupted)
    try:
        return run(args)
    except (KeyboardInterrupt, Interrupted):
        # The library records each complete image renamed into place, under the lock
        # every rename takes: what it says is what is on disk.
        if raytracer._raytracer._committed(args.output):
            print(f"interrupted after {args.output} was written; it holds the complete new image", file=sys.stderr)
            return 0
        print(f"interrupted; {args.output} left as it was", file=sys.stderr)
        return EXIT_INTERRUPTED
    except ValueError as error:
        print(f"error: {as_flags(str(error))}", file=sys.stderr)
        return EXIT_ERROR
    except (OSError, TypeError) as error:
        print(f"error: {error}", file=sys.stderr)
        return EXIT_ERROR
    except Exception as error:  # noqa: BLE001 - Dask's own errors, such as KilledWorker
        print(f"error: {type(error).__name__}: {error}", file=sys.stderr)
        return EXIT_ERROR


def run(args: argparse.Namespace) -> int:
    # Before any work, as `raytracer render`: a typo or a read-only folder costs nothing.
    raytracer.check_output(args.output)
    check_not_input(args.scene, args.output)
    if args.scheduler is not None and (args.workers is not None or args.threads is not None):
        raise ValueError("--workers and --threads set up a local cluster; not with --scheduler")
    args.workers = 2 if args.workers is None else args.workers
    args.threads = 0 if args.threads is None else args.threads
    if args.workers < 1:
        raise ValueError(f"invalid --workers: {args.workers} is not at least 1")
    if args.threads < 0:
        raise ValueError(f"invalid --threads: {args.threads} is not at least 0")
    # Options without a flag here (camera_to_world, intrinsics) are left to the file.
    options = {name: getattr(args, name, None) for name in raytracer.distributed.OPTIONS}
    with cluster_client(args) as client:
        linear, info = raytracer.distributed._render(
            args.scene, client, tile_size=args.tile_size, ship=args.ship, on_tile=None, options=options
        )
    if not args.quiet:
        if info["spp_in_mode"] != info["spp"]:
            print(
                f"warning: --spp {info['spp']} applies to full mode only; "
                f"{info['mode']} mode takes one sample per pixel",
                file=sys.stderr,
            )
        for warning in info["warnings"]:
            print(f"warning: {warning}", file=sys.stderr)
    raytracer.write_image(linear, args.output, info["mode"], info["exposure"], info["tonemap"])
    return 0


def check_not_input(scene: str, output: str) -> None:
    """Refuses to write the image over the scene file itself."""
    try:
        same = os.path.samefile(scene, output)
    except OSError:
        return
    if same:
        raise ValueError(f"cannot write {output}: it is the scene file")


class cluster_client:
    """A client of ``--scheduler``, or of a local cluster it starts and stops."""

    def __init__(self, args: argparse.Namespace) -> None:
        self.args = args
        self.cluster = None
        self.client = None

    def __enter__(self):
        from distributed import Client, LocalCluster

        if self.args.scheduler is not None:
            self.client = Client(self.args.scheduler)
            return self.client
        import dask

        threads = self.args.threads or max(1, (os.cpu_count() or 1) // self.args.workers)
        # Tiles are independent and small: the scheduler's queuing of them (saturation
        # 1.1) only makes each worker wait a round trip for its next tile.
        with dask.config.set({"distributed.scheduler.worker-saturation": float("inf")}):
            self.cluster = LocalCluster(
                n_workers=self.args.workers,
                threads_per_worker=1,
                processes=True,
                host="127.0.0.1",
                dashboard_address="127.0.0.1:0",
                silence_logs=logging.ERROR,
                env={"RAYON_NUM_THREADS": str(threads)},
            )
        self.client = Client(self.cluster)
        return self.client

    def __exit__(self, *exc: object) -> None:
        if self.client is not None:
            self.client.close()
        if self.cluster is not None:
            self.cluster.close()


if __name__ == "__main__":
    sys.exit(main())
