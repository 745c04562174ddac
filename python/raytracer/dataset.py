"""Frames written as a dataset: one file per output and a camera JSON file per frame.

>>> import raytracer, raytracer.dataset
>>> scene = raytracer.Scene("examples/cornell-box/scene.obj")
>>> camera = dict(look_from=(0, 0.7, 1.75), look_to=(0, 0.7, 0), width=64, height=64)
>>> frame = scene.render(aovs=["depth", "object_id"], **camera)
>>> record = raytracer.dataset.write_frame(scene, 7, frame, "out", **camera)
>>> sorted(record["files"])
['camera', 'color', 'depth', 'object_id']

The files of frame ``i`` in the output folder, named by the frame's index (six
digits) and the output's name, as BlenderProc-style loaders expect:

- ``000007_color.png``: the colour as the command line writes it (post-processed with
  the frame's mode, exposure and tone map), or ``000007_color.exr`` (the linear
  values, ``color_format="exr"``);
- ``000007_depth.npy``, ``_normal.npy``, ``_albedo.npy``, ``_alpha.npy`` (``float32``)
  and ``_object_id.npy``, ``_material_id.npy`` (``int32``, -1 on a miss): each output
  rendered, as :func:`raytracer.render` returns it;
- ``000007_camera.json``: the frame's pose (:func:`camera_pose`).

Every file is written atomically (a temporary file, then a rename), so a frame
written again (a task rerun after a lost Dask worker) replaces its files whole, and a
reader never sees half a file. :func:`raytracer.distributed.render_many` with
``output_dir=`` calls :func:`write_frame` on the workers.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
import threading
from typing import Any, Optional

import numpy as np

import raytracer
from raytracer.cameras import opencv_from_camera_to_world

__all__ = ["COLOR_FORMATS", "camera_pose", "check_output_dir", "frame_files", "output_path", "write_frame"]

#: The colour's file formats: ``png`` (8-bit, post-processed) or ``exr`` (linear).
COLOR_FORMATS = ("png", "exr")


def output_path(output_dir: "str | os.PathLike[str]", color_format: str = "png") -> str:
    """The absolute path of ``output_dir`` (as this process names it; nothing is
    asked of the file system); a ``ValueError`` naming the argument when it is not a
    path, or when ``color_format`` is not one of :data:`COLOR_FORMATS`."""
    if color_format not in COLOR_FORMATS:
        raise ValueError(f"invalid color_format: {color_format!r} is not one of {', '.join(COLOR_FORMATS)}")
    try:
        return os.path.abspath(os.fspath(output_dir))
    except TypeError:
        raise ValueError(f"invalid output_dir: {output_dir!r} is not a path") from None


def check_output_dir(output_dir: "str | os.PathLike[str]", color_format: str = "png") -> str:
    """The absolute path of ``output_dir``, made if missing; a ``ValueError`` naming
    the argument when it is not a folder this process can write in, or when
    ``color_format`` is not one of :data:`COLOR_FORMATS`."""
    folder = output_path(output_dir, color_format)
    if os.path.exists(folder) and not os.path.isdir(folder):
        raise ValueError(f"invalid output_dir: {folder} is not a folder")
    try:
        os.makedirs(folder, exist_ok=True)
        # Asked of the file system itself: permissions alone do not tell (a read-only
        # mount, root).
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as error:
        raise ValueError(f"invalid output_dir: cannot write in {folder}: {error.strerror or error}") from None
    return folder


def frame_files(output_dir: "str | os.PathLike[str]", index: int, outputs, color_format: str = "png") -> dict:
    """The paths :func:`write_frame` writes for frame ``index`` with these outputs
    (``color`` and the extra outputs' names), and its ``camera`` JSON file."""
    stem = os.path.join(os.fspath(output_dir), f"{index:06d}_")
    files = {}
    for name in outputs:
        files[name] = stem + (f"color.{color_format}" if name == "color" else f"{name}.npy")
    files["camera"] = stem + "camera.json"
    return files


def camera_pose(options: dict, resolved: dict) -> dict:
    """The pose of a frame as datasets give it: ``width``, ``height``,
    ``cam2world_opengl`` (4x4, the renderer's ``camera_to_world``: looking down -Z, +Y
    up), OpenCV's world-to-camera ``R_world2cam_opencv`` and ``t_world2cam_opencv``,
    and ``K``, the 3x3 intrinsics in pixels (the top-left pixel's centre at (0, 0)).

    ``options`` are the frame's render options (its camera as given:
    ``camera_to_world`` or ``look_from``/``look_to``/``up``, ``intrinsics`` or
    ``fov``), ``resolved`` what :meth:`raytracer.Scene.options` makes of them (the
    scene file's camera where the options leave it out)."""
    width, height = int(resolved["width"]), int(resolved["height"])
    if options.get("camera_to_world") is not None:
        pose = np.asarray(options["camera_to_world"], dtype=np.float64).reshape(4, 4)
    else:
        # Three-vectors as plain floats: numpy's small-array calls (np.cross) cost more
        # than the arithmetic, once per frame.
        eye = [float(v) for v in resolved["look_from"]]
        back = _unit([e - float(t) for e, t in zip(eye, resolved["look_to"])])
        right = _unit(_cross([float(v) for v in resolved["up"]], back))
        pose = np.eye(4)
        pose[:3, 0], pose[:3, 1], pose[:3, 2], pose[:3, 3] = right, _cross(back, right), back, eye
    if options.get("intrinsics") is not None:
        fx, fy, cx, cy = (float(v) for v in options["intrinsics"])
    else:
        # The vertical field of view spans the image's height, edge to edge.
        fx = fy = (height / 2) / math.tan(math.radians(float(resolved["fov"])) / 2)
        cx, cy = (width - 1) / 2, (height - 1) / 2
    rotation, translation = opencv_from_camera_to_world(pose)
    return {
        "width": width,
        "height": height,
        "cam2world_opengl": pose.tolist(),
        "R_world2cam_opencv": rotation.tolist(),
        "t_world2cam_opencv": translation.tolist(),
        "K": [[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]],
    }


def _cross(a: list, b: list) -> list:
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def _unit(v: list) -> list:
    length = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    return [x / length for x in v]


def write_frame(
    scene: "raytracer.Scene",
    index: int,
    frame: Any,
    output_dir: "str | os.PathLike[str]",
    *,
    color_format: str = "png",
    resolved: Optional[dict] = None,
    **options: Any,
) -> dict:
    """Writes ``frame`` (what :meth:`raytracer.Scene.render` returned for ``options``:
    the linear image, or a dict of ``color`` and the extra outputs) as frame
    ``index`` in ``output_dir`` (see the module's documentation) and returns its
    record: ``{"frame": index, "files": {output: path, ..., "camera": path}, "pose":
    camera_pose(...)}``. ``options`` are those the frame was rendered with (all but
    ``aovs``: its camera, size, mode, exposure, tone map), resolved by ``scene`` as
    the render resolved them, unless ``resolved`` gives what
    :meth:`raytracer.Scene.options` returned for them."""
    options.pop("aovs", None)
    if resolved is None:
        resolved = scene.options(**options)
    outputs = frame if isinstance(frame, dict) else {"color": frame}
    files = frame_files(output_dir, index, outputs, color_format)
    for name, path in files.items():
        if name == "color":
            # Atomic, as the command line writes: PNG post-processed, EXR linear.
            raytracer.write_image(
                outputs["color"], path, mode=resolved["mode"], exposure=resolved["exposure"], tonemap=resolved["tonemap"]
            )
        elif name != "camera":
            _replace(path, lambda f, array=outputs[name]: np.save(f, np.asarray(array), allow_pickle=False))
    pose = camera_pose(options, resolved)
    # No indent: the json module's C encoder then writes it (indented, the Python
    # one: a millisecond a frame).
    _replace(files["camera"], lambda f: f.write(json.dumps({"frame": index, **pose}).encode()))
    return {"frame": index, "files": files, "pose": pose}


def _replace(path: str, write) -> None:
    """Writes ``path`` atomically: ``write(file)`` into a temporary file beside it,
    then a rename over it. The temporary file is named by this process and thread,
    the only writers of this frame's files here (``tempfile.mkstemp``'s random names
    cost a tenth of a frame's write)."""
    folder, name = os.path.split(path)
    temporary = os.path.join(folder, f".{name}.{os.getpid()}-{threading.get_ident()}.tmp")
    try:
        with open(temporary, "wb") as f:
            write(f)
        os.replace(temporary, path)
    except BaseException:
        try:
            os.unlink(temporary)
        except OSError:
            pass
        raise
