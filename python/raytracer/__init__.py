"""A CPU ray tracer for OBJ/MTL, PLY, glTF 2.0 and TOML scenes, from Python.

Four modes: ``full`` (Whitted-style: Phong lighting, hard shadows, reflection and
refraction; the default), ``depth``, ``normal`` and ``path`` (a physically based path
tracer).

The package is a thin layer over the Rust library (the ``raytracer`` command's):

>>> import raytracer
>>> linear = raytracer.render("examples/cornell-box/scene.toml", width=320)
>>> linear.shape, linear.dtype
((240, 320, 3), dtype('float32'))
>>> rgb = raytracer.postprocess(linear)          # uint8, as the PNG holds it
>>> raytracer.write_image(linear, "cornell.png")  # or .exr: the linear values

- :func:`render` renders a scene file (or a :class:`Scene` read once) into the linear
  image before post-processing, a ``float32`` array ``(height, width, 3)``; ``tile=``
  renders part of it, bit-identical to the same pixels of the whole.
- :func:`postprocess` turns a linear image into 8-bit RGB exactly as the command line
  does before writing a PNG; :func:`write_image` and :func:`write_png` write files
  atomically, as the command line does.
- :meth:`Scene.from_mesh` makes a scene of a mesh held as arrays (vertices and faces);
  :meth:`Scene.intersect` casts rays of your own: the closest hit of each row of
  ``(n, 3)`` arrays of origins and directions, as arrays of distances, triangle
  indices (in the file's order) and barycentric coordinates;
  :meth:`Scene.occluded` whether anything blocks each ray within a distance.
- :mod:`raytracer.distributed` renders tiles on a Dask cluster (``pip install
  "raytracer[distributed]"``); ``python -m raytracer.distributed`` is its command.
  Its ``render_many`` renders a frame per camera, the workers writing them as a
  dataset with ``output_dir=`` (:mod:`raytracer.dataset`: a file per output and the
  camera's pose as JSON).

Every render call takes the keyword options named in :data:`OPTIONS` (``width``,
``height``, ``fov``, ``look_from``, ``look_to``, ``up``, ``camera_to_world``,
``intrinsics``, ``mode``, ``depth``, ``spp``, ``exposure``, ``seed``, ``tonemap``,
``aperture_radius``, ``focus_distance``, ``default_light``, ``env``, ``env_strength``,
``env_rotation``, ``background``) and ``progress``. They behave as the command line's
flags: each one given replaces the TOML scene file's value, each one left out
(``None``) keeps it, and the defaults apply last.
Errors are exceptions with the command line's messages, naming the keyword:
``ValueError`` for bad options, :class:`SceneError` (an ``OSError``) for unreadable or
malformed scenes. Warnings are :class:`RaytracerWarning` warnings. Ctrl-C raises
``KeyboardInterrupt`` within a fraction of a second. Rendered images are
:class:`Image` arrays, which Jupyter shows as their PNG.
"""

# numpy first: the extension module makes numpy arrays, and importing numpy late (in
# the middle of a call) could fail on a pending KeyboardInterrupt.
import numpy as _numpy  # noqa: F401

from ._image import Image
from ._raytracer import (
    OPTIONS,
    RaytracerWarning,
    Scene,
    SceneError,
    __version__,
    check_output,
    postprocess,
    render,
    write_image,
    write_png,
)

__all__ = [
    "OPTIONS",
    "Image",
    "RaytracerWarning",
    "Scene",
    "SceneError",
    "__version__",
    "check_output",
    "postprocess",
    "render",
    "write_image",
    "write_png",
]
