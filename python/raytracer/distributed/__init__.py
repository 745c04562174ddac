"""Rendering on a Dask cluster: the image cut into tiles, one task per tile.

>>> from dask.distributed import Client
>>> import raytracer.distributed
>>> client = Client("tcp://scheduler:8786")
>>> linear = raytracer.distributed.render("scene.toml", client, width=3840, spp=16)

:func:`render` returns exactly (bit for bit) what :func:`raytracer.render` returns for
the same scene and options. How it works:

1. **The scene.** By default the client checks whether every worker sees the same
   scene files at the same absolute path (a shared file system): it hashes the files
   the scene reads (the scene file, an OBJ file's MTL libraries, a TOML file's meshes
   and their MTL libraries) and asks each worker to hash its copies. If all agree the
   workers read the path; otherwise the client *ships* the scene: it reads those files
   and scatters their bytes to every worker, which writes them to a temporary folder
   (same relative layout) and reads the scene from there, opening no file outside
   it. ``ship=True`` or ``ship=False`` skips the check. Only files inside the scene's
   folder are shipped: a scene that reads a file elsewhere (an absolute path, ``..``)
   cannot be shipped. The check covers the workers connected when the render starts.
2. **The options** are resolved on a worker, exactly as :func:`raytracer.render`
   resolves them (arguments over the TOML file's values over the defaults).
3. **Tiles** of ``tile_size`` x ``tile_size`` pixels (narrower at the right and bottom
   edges) are rendered by :meth:`raytracer.Scene.render` with ``tile=``, each worker
   process reading and building the scene once and keeping it for the next renders of
   the same files (the last :data:`KEEP_SCENES` scenes, keyed by the digests of every
   file the scene reads, so that a changed file is read again; :func:`forget` drops
   them). Each tile is copied into the image as soon as it arrives and its result
   released on the cluster.
4. **A lost worker**: Dask recomputes the tiles the worker was rendering, or had
   rendered but not yet sent, on the workers left (up to Dask's
   ``distributed.scheduler.allowed-failures`` times per tile). Tiles are pure
   functions of scene, options and position, so the image stays bit-identical.

Workers need this package installed (the same version as the client). Each worker
renders a tile on all its cores (rayon threads); ``RAYON_NUM_THREADS`` in a worker's
environment limits them. One worker thread per process (``--nthreads 1``) is enough.

``python -m raytracer.distributed SCENE -o OUT.png`` is the command-line version
(``--help`` lists its flags).

:func:`render_many` renders one whole frame per camera instead (several frames to a
task), yielding the frames, or with ``output_dir=`` having the workers write them
(:func:`raytracer.dataset.write_frame`) and yielding their small records.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import ipaddress
import os
import pickle
import shutil
import sys
import tempfile
import threading
import uuid
from collections import OrderedDict
from typing import Any, Callable, Iterable, Iterator, Optional, Sequence

import numpy as np

import raytracer

__all__ = ["forget", "render", "render_many", "scene_files", "tiles"]

#: The keyword options :func:`render` passes on to :meth:`raytracer.Scene.render`: all
#: of :data:`raytracer.OPTIONS` but the environment's, which belong to the scene file.
OPTIONS = tuple(name for name in raytracer.OPTIONS if name not in ("env", "env_strength", "env_rotation", "background"))



def render(
    scene: "str | os.PathLike[str]",
    client: Any,
    *,
    tile_size: int = 64,
    ship: Optional[bool] = None,
    on_tile: Optional[Callable[[int, int], None]] = None,
    **options: Any,
) -> np.ndarray:
    """Renders ``scene`` on the cluster of ``client`` and returns the linear image.

    The result is the same array as ``raytracer.render(scene, **options)``: ``float32``,
    shape ``(height, width, 3)``, bit-identical. ``options`` are those of
    :func:`raytracer.render` (``width``, ``height``, ``fov``, ``look_from``,
    ``look_to``, ``up``, ``mode``, ``depth``, ``spp``, ``exposure``, ``seed``,
    ``tonemap``, ``aperture_radius``, ``focus_distance``);
    ``None`` or left out keeps the TOML scene file's value, else the default.

    ``client`` is a synchronous ``dask.distributed.Client``. ``tile_size`` is the side
    of the square tiles in pixels. ``ship`` chooses how workers get the scene: ``None``
    checks whether they see the client's files at the same path and ships them if not,
    ``True`` always ships, ``False`` never does (see the module's documentation).
    ``on_tile(done, total)`` is called on the client after each tile arrives.

    Raises what :func:`raytracer.render` raises (``ValueError`` for bad options,
    :class:`raytracer.SceneError` for a bad scene), from the worker that found it.
    """
    return _render(scene, client, tile_size=tile_size, ship=ship, on_tile=on_tile, options=options)[0]


def _render(
    scene: "str | os.PathLike[str]",
    client: Any,
    *,
    tile_size: int,
    ship: Optional[bool],
    on_tile: Optional[Callable[[int, int], None]],
    options: dict,
) -> "tuple[np.ndarray, dict]":
    """:func:`render`, also returning the resolved options (a dict as
    :meth:`raytracer.Scene.options` returns, plus the scene's ``warnings``)."""
    from distributed import as_completed

    unknown = sorted(set(options) - set(OPTIONS))
    if unknown:
        raise TypeError(f"render() got an unexpected keyword argument {unknown[0]!r}")
    if isinstance(tile_size, bool) or not isinstance(tile_size, int) or tile_size < 1:
        raise ValueError(f"invalid tile_size: {tile_size!r} is not a whole number of at least 1")
    given = {name: value for name, value in options.items() if value is not None}
    # The tasks' keys: this render's own, whatever the scene's key.
    task = f"raytracer-{uuid.uuid4().hex}"
    with _scene_on_workers(client, scene, ship) as (key, path, bundle):
        info = client.submit(_prepare, key, path, bundle, given, key=f"{task}-options").result()
        width, height = info["width"], info["height"]
        parts = tiles(width, height, tile_size)
        keys = [f"{task}-tile-{x}-{y}" for (x, y, _, _) in parts]
        futures = client.map(
            _render_tile, parts, job=key, path=path, bundle=bundle, options=given, key=keys
        )
        where = dict(zip(keys, parts))
        image = np.empty((height, width, 3), dtype=np.float32)
        done = 0
        waiting = as_completed(futures)
        # Only `as_completed` keeps the futures now: each tile's result is released on
        # the cluster once it is copied into the image.
        del futures
        # The tiles finished since the last batch, fetched in one request. `gather`
        # waits for a tile lost with its worker to be rendered again.
        direct = _direct(client)
        for batch in waiting.batches():
            for future, part in zip(batch, client.gather(batch, direct=direct)):
                x, y, w, h = where[future.key]
                image[y : y + h, x : x + w] = part
                future.release()
                done += 1
                if on_tile is not None:
                    on_tile(done, len(parts))
        return image, info


@contextlib.contextmanager
def _scene_on_workers(client: Any, scene: "str | os.PathLike[str]", ship: Optional[bool]):
    """Makes the scene readable by the workers (checked or shipped, see the module's
    documentation) for the body of the ``with``; yields the key under which workers
    keep it, its path and the shipped bundle (or ``None``). Afterwards, frees what
    the workers must not keep."""
    # Workers may have another working folder; a shared file system has the same
    # absolute paths. Not resolved: a link must mean on each worker what it means there.
    path = os.path.abspath(os.fspath(scene))
    job = f"raytracer-{uuid.uuid4().hex}"
    bundle = None
    # The workers keep a scene between renders under a key that changes whenever a
    # file it reads does (its identity); a scene read on the workers' own terms
    # (`ship=False`) has none the client can vouch for, and is read per render.
    key = job
    try:
        if ship is None:
            shared, identity = _workers_share(client, path, job)
            ship = not shared
            if shared and identity is not None:
                key = f"raytracer-path-{identity}"
        if ship:
            contents = _bundle(path)
            key = f"raytracer-shipped-{_identity(contents)}"
            # In a list: a dict would be scattered as one future per value.
            [bundle] = client.scatter([contents], broadcast=True, hash=False)
            del contents
        yield key, path, bundle
    finally:
        if bundle is not None:
            bundle.release()
        if key == job:
            try:
                client.run(_forget, job)
            except Exception:  # noqa: BLE001 - a worker gone or a closed client: nothing to free
                pass


#: What :func:`render_many` puts in one task at most: frames of this many camera
#: samples in all (width x height x samples per pixel), and this many frames.
TASK_SAMPLES = 1 << 20
TASK_FRAMES = 16
#: Tasks per worker thread that :func:`render_many` leaves at least, to balance the
#: load.
TASKS_PER_THREAD = 4


def render_many(
    scene: "str | os.PathLike[str]",
    cameras: Iterable[dict],
    client: Any,
    *,
    aovs: Optional[Sequence[str]] = None,
    output_dir: "str | os.PathLike[str] | None" = None,
    color_format: str = "png",
    writer: Optional[Callable[..., Any]] = None,
    ship: Optional[bool] = None,
    frames_per_task: Optional[int] = None,
    **options: Any,
) -> Iterator["tuple[int, Any]"]:
    """Renders one frame per camera on the cluster of ``client`` and yields ``(index,
    frame)`` as frames finish (in no fixed order): ``index`` is the camera's position
    in ``cameras``, ``frame`` what :func:`raytracer.render` returns for ``scene`` with
    that camera's options over ``options`` (and ``aovs``: a dict of ``color`` and each
    output asked for), bit for bit. Every frame is yielded once.

    Each camera is a dict of render options (``camera_to_world``, ``intrinsics``,
    ``look_from``, ``fov``, ...). The scene reaches the workers as :func:`render`'s
    does, once per worker process for all the frames (kept between calls while its
    files do not change). Frames go to the workers in tasks of ``frames_per_task``
    consecutive cameras; by default as many as make some
    :data:`TASK_SAMPLES` camera samples (width x height x samples per pixel, as far
    as the options say) and at most :data:`TASK_FRAMES`, leaving at least
    :data:`TASKS_PER_THREAD` tasks per worker thread: Dask spends a few milliseconds
    of the client's and the worker's time on each task, as much as a small frame
    takes to render. A lost worker costs only its tasks' frames, which Dask renders
    again elsewhere. Raises what :func:`raytracer.render` raises, from the worker
    that found it, when its frame is reached.

    ``output_dir``: the workers write each frame there themselves, as
    :func:`raytracer.dataset.write_frame` does (colour as PNG, or linear EXR with
    ``color_format="exr"``; each extra output as ``.npy``; the pose as JSON), and
    ``frame`` is the small record it returns (``{"frame": index, "files": {output:
    path}, "pose": {...}}``) instead of the arrays: the frames never travel, which is
    most of what Dask costs on small frames (BENCHMARKS.md, ``render_many``). The
    folder must be one every worker sees at the same path (shared storage, or the
    client's machine for a local cluster); it is made if missing, and a path that is
    not a folder every connected worker can write in is a ``ValueError`` naming
    ``output_dir``, raised by this call. A frame rendered again after a lost worker
    replaces its files whole (each is written atomically).
    ``writer``: a function of your own run on the workers instead,
    ``writer(scene, index, frame, **options)`` with the worker's
    :class:`raytracer.Scene`, the frame and the options it was rendered with
    (``aovs`` among them), returning what to yield for it.

    Arguments are checked by this call, before any frame is rendered.
    """
    cameras = [dict(camera) for camera in cameras]
    for camera in [options, *cameras]:
        unknown = sorted(set(camera) - set(OPTIONS))
        if unknown:
            raise TypeError(f"render_many() got an unexpected option {unknown[0]!r}")
    if frames_per_task is not None and (
        isinstance(frames_per_task, bool) or not isinstance(frames_per_task, int) or frames_per_task < 1
    ):
        raise ValueError(f"invalid frames_per_task: {frames_per_task!r} is not a whole number of at least 1")
    base = {name: value for name, value in options.items() if value is not None}
    if aovs is not None:
        base["aovs"] = list(aovs)
    frames = [{**base, **camera} for camera in cameras]
    if frames_per_task is None:
        frames_per_task = _frames_per_task(client, frames)
    groups = [range(i, min(i + frames_per_task, len(frames))) for i in range(0, len(frames), frames_per_task)]
    if output_dir is not None and writer is not None:
        raise ValueError("render_many() takes output_dir or writer, not both")
    if writer is not None and not callable(writer):
        raise ValueError(f"invalid writer: {writer!r} is not callable")
    if output_dir is not None:
        from raytracer.dataset import output_path, write_frame

        # Absolute: a worker's working folder may be another.
        output_dir = output_path(output_dir, color_format)
        # Every worker connected now must be able to write there (made if missing).
        client.wait_for_workers(1)
        for error in client.run(_check_output_dir, output_dir, color_format).values():
            if error is not None:
                raise ValueError(error)
        writer = functools.partial(write_frame, output_dir=output_dir, color_format=color_format)
    return _render_many(scene, client, frames, groups, writer, ship)


def _render_many(
    scene: "str | os.PathLike[str]",
    client: Any,
    frames: "list[dict]",
    groups: "list[range]",
    writer: Optional[Callable[..., Any]],
    ship: Optional[bool],
) -> Iterator["tuple[int, Any]"]:
    """:func:`render_many`'s generator, its arguments checked."""
    from distributed import as_completed

    with _scene_on_workers(client, scene, ship) as (key, path, bundle):
        task = f"raytracer-{uuid.uuid4().hex}"
        keys = [f"{task}-frames-{group.start}-{group.stop}" for group in groups]
        # One message for all the tasks (`submit` per task costs a round trip each).
        futures = client.map(
            _render_frames,
            [[frames[i] for i in group] for group in groups],
            [group.start for group in groups],
            job=key,
            path=path,
            bundle=bundle,
            writer=writer,
            key=keys,
        )
        index = dict(zip(keys, groups))
        waiting = as_completed(futures)
        del futures
        # The tasks finished since the last batch, fetched in one request. `gather`
        # waits for a task lost with its worker to be rendered again.
        direct = _direct(client)
        for batch in waiting.batches():
            for future, rendered in zip(batch, client.gather(batch, direct=direct)):
                future.release()
                yield from zip(index[future.key], rendered)


def _frames_per_task(client: Any, frames: "list[dict]") -> int:
    """:func:`render_many`'s default ``frames_per_task`` (see there)."""
    threads = sum(w.get("nthreads", 1) for w in client.scheduler_info()["workers"].values()) or 1

    def samples(frame: dict) -> int:
        width, height = frame.get("width"), frame.get("height")
        if width is None and height is None:
            width, height = 640, 480
        width = width if width is not None else height * 4 // 3
        height = height if height is not None else width * 3 // 4
        spp = frame.get("spp") or (64 if frame.get("mode") == "path" else 1)
        return max(1, int(width) * int(height) * int(spp))

    most = max((samples(frame) for frame in frames), default=1)
    fewest_tasks = max(1, len(frames) // (TASKS_PER_THREAD * threads))
    return max(1, min(TASK_FRAMES, TASK_SAMPLES // most, fewest_tasks))


def _direct(client: Any) -> Optional[bool]:
    """How the client fetches results: the client's own choice
    (``Client(direct_to_workers=...)``) if it made one; otherwise straight from the
    workers when the scheduler is on this machine (a local cluster, whose workers
    this process can reach), since through the scheduler every frame travels twice
    (BENCHMARKS.md's render_many figure); else Dask's default, through the
    scheduler, which a client outside the cluster's network can always reach."""
    if client.direct_to_workers is not None:
        return client.direct_to_workers
    from distributed.comm import get_address_host

    address = client.scheduler.address
    if address.startswith("inproc://"):
        return True
    try:
        host = get_address_host(address)
        return True if host == "localhost" or ipaddress.ip_address(host).is_loopback else None
    except ValueError:
        return None


def forget(client: Any) -> None:
    """Drops the scenes the workers of ``client`` keep between renders (at most
    :data:`KEEP_SCENES` per worker process), and their copies of shipped files."""
    client.run(_forget_all)


def tiles(width: int, height: int, size: int) -> "list[tuple[int, int, int, int]]":
    """The tiles ``(x, y, w, h)`` covering a ``width`` x ``height`` image, row by row:
    squares of ``size`` pixels, narrower in the last column and row."""
    return [
        (x, y, min(size, width - x), min(size, height - y))
        for y in range(0, height, size)
        for x in range(0, width, size)
    ]


# --- The scene's files: what to check and what to ship -----------------------------


def scene_files(scene: "str | os.PathLike[str]") -> "list[str]":
    """The files a render of ``scene`` reads, as absolute normalized paths, the scene
    file first: an OBJ file's MTL libraries and their textures, a TOML file's meshes
    with what they name, a glTF file's buffers and images. Files looked for and not
    found are among them. The library's own readers tell (the scene is loaded).

    Raises ``OSError`` when the scene file itself cannot be read.
    """
    path = os.path.abspath(os.fspath(scene))
    with open(path, "rb"):
        pass
    # Loading the scene to learn its files costs what a render's load does: a render
    # of the same files again (the frames of an animation) looks them up instead.
    known = _known_files.get(path)
    if known is not None and known[0] == _signature(known[1]):
        return list(known[1])
    files = [os.fspath(file) for file in raytracer._raytracer._scene_files(path, False)["asked"]]
    _known_files[path] = (_signature(files), files)
    return list(files)


#: The files of the scenes :func:`scene_files` loaded, with their signature then.
_known_files: "dict[str, tuple[list, list[str]]]" = {}


def _signature(files: Iterable[str]) -> list:
    """Size and modification time of each file (``None`` when missing): a file that
    changes, appears or disappears changes it."""
    signature = []
    for file in files:
        try:
            stat = os.stat(file)
            signature.append((stat.st_size, stat.st_mtime_ns))
        except OSError:
            signature.append(None)
    return signature


def _digests(files: Iterable[str]) -> "list[Optional[str]]":
    """The SHA-256 of each file, ``None`` for one that cannot be read."""
    digests: "list[Optional[str]]" = []
    for file in files:
        try:
            digest = hashlib.sha256()
            with open(file, "rb") as f:
                for block in iter(lambda: f.read(1 << 20), b""):
                    digest.update(block)
            digests.append(digest.hexdigest())
        except OSError:
            digests.append(None)
    return digests


def _workers_share(client: Any, path: str, job: str) -> "tuple[bool, Optional[str]]":
    """Whether every worker connected now reads the same files at the scene's path as
    the client (true when the client cannot read the scene: then only the workers can),
    and the identity of those files (``None`` if the client cannot read them)."""
    try:
        files = scene_files(path)
    except OSError:
        return True, None
    local = _digests(files)
    client.wait_for_workers(1)
    workers = list(client.scheduler_info()["workers"])
    checks = [
        client.submit(_digests, files, workers=[w], allow_other_workers=True, key=f"{job}-check-{i}")
        for i, w in enumerate(workers)
    ]
    shared = all(remote == local for remote in client.gather(checks))
    return shared, _identity({"path": path, "files": dict(zip(files, local))})


def _identity(value: Any) -> str:
    """A digest of a scene's files: their names and contents (or their digests)."""
    digest = hashlib.sha256()
    digest.update(pickle.dumps(value, protocol=4))
    return digest.hexdigest()


def _bundle(path: str) -> dict:
    """The bytes of every file the scene reads, by path relative to the scene's
    folder, to be written out on a worker in the same layout. Only files inside that
    folder go: a scene that reads one outside it (named by an absolute path, by ``..``,
    or through a link) is a ``ValueError`` naming it."""
    folder = os.path.dirname(path)
    found = raytracer._raytracer._scene_files(path, True)
    outside = [os.fspath(file) for file in found["refused"] if os.path.exists(file)]
    if outside:
        said = [
            line
            for line in [found["error"] or "", *found["warnings"]]
            if "outside the scene's folder" in line
        ]
        raise ValueError(
            f"cannot ship {path} to the workers: it reads {outside[0]}, outside its folder "
            f"{folder}" + "".join(f"\n{line}" for line in said) + "\nPut the files the "
            "scene reads in its folder, or the scene on a path the workers share (ship=False)"
        )
    contents = {}
    for file in found["asked"]:
        if os.path.isfile(file):
            with open(file, "rb") as f:
                contents[os.path.relpath(file, folder)] = f.read()
    # A file that cannot be read is not shipped: reading the scene on the worker
    # reports it, naming the file.
    return {"root": folder, "main": os.path.basename(path), "files": contents}


# --- On the workers -------------------------------------------------------------------

_jobs_lock = threading.Lock()
_jobs: "OrderedDict[str, _Job]" = OrderedDict()
#: Scenes a worker process keeps: those of the last renders, by the identity of their
#: files, read again by none of the next renders that read the same files; the oldest
#: is dropped.
KEEP_SCENES = 2
#: How many times this process has read a scene (for the tests).
_loads = 0


class _Job:
    """A scene in a worker process: read once, by the first task that needs it, while
    the process's other tasks for the same scene wait for it."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.scene: Optional[raytracer.Scene] = None
        self.folder: Optional[str] = None

    def load(self, path: str, bundle: Optional[dict]) -> raytracer.Scene:
        with self.lock:
            if self.scene is None:
                self.scene = self._read(path, bundle)
            return self.scene

    def _read(self, path: str, bundle: Optional[dict]) -> raytracer.Scene:
        global _loads
        _loads += 1
        if bundle is None:
            return raytracer.Scene(path)
        self.folder = tempfile.mkdtemp(prefix="raytracer-scene-")
        for name, data in bundle["files"].items():
            file = os.path.join(self.folder, name)
            os.makedirs(os.path.dirname(file), exist_ok=True)
            with open(file, "wb") as f:
                f.write(data)
        try:
            # Confined: the worker reads nothing of its own on the scene's behalf.
            return raytracer.Scene(os.path.join(self.folder, bundle["main"]), confined_to=self.folder)
        except raytracer.SceneError as error:
            # Name the client's files, not this worker's copies.
            raise raytracer.SceneError(str(error).replace(self.folder, bundle["root"])) from None

    def close(self) -> None:
        self.scene = None
        if self.folder is not None:
            shutil.rmtree(self.folder, ignore_errors=True)
            self.folder = None


def _job(job: str) -> _Job:
    with _jobs_lock:
        entry = _jobs.get(job)
        if entry is None:
            entry = _jobs[job] = _Job()
            while len(_jobs) > KEEP_SCENES:
                _jobs.popitem(last=False)[1].close()
        else:
            _jobs.move_to_end(job)
        return entry


def _prepare(job: str, path: str, bundle: Optional[dict], options: dict) -> dict:
    """Task: reads the scene (kept for the tiles) and resolves the options."""
    scene = _job(job).load(path, bundle)
    info = scene.options(**options)
    info["warnings"] = scene.warnings
    return info


def _render_tile(tile: tuple, job: str, path: str, bundle: Optional[dict], options: dict) -> np.ndarray:
    """Task: renders one tile of the image."""
    return _job(job).load(path, bundle).render(tile=tile, **options)


def _render_frames(
    frames: "list[dict]",
    first: int,
    job: str,
    path: str,
    bundle: Optional[dict],
    writer: Optional[Callable[..., Any]] = None,
) -> list:
    """Task: renders whole frames, one per dict of options, the first of them frame
    ``first``: each a plain array, or a dict with ``aovs``; or what ``writer`` returns
    for it."""
    scene = _job(job).load(path, bundle)
    out = []
    with _recycled_pages():
        for index, options in enumerate(frames, first):
            frame = scene.render(**options)
            if writer is not None:
                out.append(writer(scene, index, frame, **options))
            else:
                out.append(np.asarray(frame) if isinstance(frame, np.ndarray) else {k: np.asarray(v) for k, v in frame.items()})
    return out


#: glibc's ``mallopt`` parameters (malloc.h).
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
#: What :func:`_recycled_pages` sets while frames render: blocks up to this size from
#: the heap, and at most this much free memory at its top kept.
ROOMY_MMAP_THRESHOLD = 32 << 20
ROOMY_TRIM_THRESHOLD = 64 << 20
_roomy_lock = threading.Lock()
_roomy_tasks = 0


@contextlib.contextmanager
def _recycled_pages():
    """While frames render in this process: lets glibc's malloc reuse the pages of a
    frame's freed buffers for the next, when the process was started with
    ``MALLOC_TRIM_THRESHOLD_`` (as Dask's nanny starts workers, to return freed memory
    at once). That setting turns off glibc's adaptive thresholds: every block above
    128 KiB (a 256x256 frame's colour is 768 KiB) is mapped afresh and unmapped when
    freed, and each of its pages faults again, a tenth of a small frame's CPU
    (BENCHMARKS.md, ``render_many``). The process's own settings are restored when
    the last task using this ends.
    Nothing changes elsewhere (another C library, or no such setting)."""
    global _roomy_tasks
    libc = _glibc()
    trim = os.environ.get("MALLOC_TRIM_THRESHOLD_")
    if libc is None or trim is None:
        yield
        return
    with _roomy_lock:
        if _roomy_tasks == 0:
            libc.mallopt(_M_MMAP_THRESHOLD, ROOMY_MMAP_THRESHOLD)
            libc.mallopt(_M_TRIM_THRESHOLD, ROOMY_TRIM_THRESHOLD)
        _roomy_tasks += 1
    try:
        yield
    finally:
        with _roomy_lock:
            _roomy_tasks -= 1
            if _roomy_tasks == 0:
                # glibc's values under MALLOC_TRIM_THRESHOLD_: that threshold, and
                # MALLOC_MMAP_THRESHOLD_ or the fixed 128 KiB.
                libc.mallopt(_M_MMAP_THRESHOLD, _int(os.environ.get("MALLOC_MMAP_THRESHOLD_"), 128 << 10))
                libc.mallopt(_M_TRIM_THRESHOLD, _int(trim, 128 << 10))
                # No malloc_trim(0) here: it drops every free page of the heap,
                # which the next task faults in again (1.5x the page faults of a
                # worker of 150 frames); the next free above the threshold trims.


def _int(text: Optional[str], default: int) -> int:
    try:
        return int(text) if text is not None else default
    except ValueError:
        return default


_libc: Any = None


def _glibc() -> Any:
    """glibc through ctypes, or ``None`` on another C library or system."""
    global _libc
    if _libc is None:
        _libc = False
        if sys.platform.startswith("linux"):
            import ctypes

            try:
                libc = ctypes.CDLL("libc.so.6")
                libc.gnu_get_libc_version  # noqa: B018 - glibc's own function, or AttributeError
                libc.mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
                _libc = libc
            except (OSError, AttributeError):
                pass
    return _libc or None


def _check_output_dir(output_dir: str, color_format: str) -> Optional[str]:
    """Run on every worker by :func:`render_many`: why it cannot write frames in
    ``output_dir`` (see :func:`raytracer.dataset.check_output_dir`), or ``None``.
    Returned, not raised: a worker logs what a run raises."""
    from raytracer.dataset import check_output_dir

    try:
        check_output_dir(output_dir, color_format)
    except ValueError as error:
        return str(error)
    return None


def _forget(job: str) -> None:
    """Run on every worker when a render whose scene is not kept ends: drops its scene
    and shipped files."""
    with _jobs_lock:
        entry = _jobs.pop(job, None)
    if entry is not None:
        entry.close()


def _forget_all() -> None:
    """Run on every worker by :func:`forget`."""
    with _jobs_lock:
        entries = list(_jobs.values())
        _jobs.clear()
    for entry in entries:
        entry.close()
