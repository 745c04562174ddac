#!/usr/bin/env python3
"""Blender Cycles (the `bpy` module) on the dragon scene: import the OBJ, then render
1024x768 on the CPU at 1 sample with no bounces, lit by the two point lights. Prints one
JSON object with medians; each run starts from an empty scene.

The importer keeps the OBJ's axes (no Y-up to Z-up turn), so the camera is placed with
the same LookAt basis as SPEC.md (Blender cameras also look down -z with +y up). The
materials are those the importer makes from the .mtl (Principled BSDF).
"""

from __future__ import annotations

import contextlib
import math
import os
import statistics
import sys
import time

import common

try:
    import bpy
    from mathutils import Matrix
except ImportError as err:
    common.skip("cycles", f"cannot import bpy ({err}); pip install bpy (Python 3.11 only)")


@contextlib.contextmanager
def quiet_stdout():
    """Blender prints progress on the C-level stdout; keep it off our JSON line."""
    sys.stdout.flush()
    saved = os.dup(1)
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    try:
        yield
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)
        os.close(devnull)


def import_obj(path: str) -> None:
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.obj_import(filepath=path, forward_axis="Y", up_axis="Z")


def set_up(out: str | None) -> None:
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    cycles = scene.cycles
    cycles.device = "CPU"
    cycles.samples = 1
    cycles.use_adaptive_sampling = False
    cycles.use_denoising = False
    cycles.max_bounces = 0
    scene.render.threads_mode = "AUTO"
    scene.render.resolution_x = common.WIDTH
    scene.render.resolution_y = common.HEIGHT
    scene.render.resolution_percentage = 100
    # No world: a background would be sampled as a light, adding rays the others lack.
    scene.world = None

    camera = bpy.data.cameras.new("camera")
    camera.sensor_fit = "VERTICAL"
    camera.angle_y = math.radians(common.FOV_DEGREES)
    camera_object = bpy.data.objects.new("camera", camera)
    origin, right, up, backward = common.camera_basis()
    camera_object.matrix_world = Matrix(
        [[right[i], up[i], backward[i], origin[i]] for i in range(3)] + [[0, 0, 0, 1]]
    )
    scene.collection.objects.link(camera_object)
    scene.camera = camera_object

    for i, (position, intensity) in enumerate(common.LIGHTS):
        light = bpy.data.lights.new(f"light{i}", "POINT")
        light.shadow_soft_size = 0.0
        light.energy = 10.0 * max(intensity)
        light.color = tuple(c / max(intensity) for c in intensity)
        light_object = bpy.data.objects.new(f"light{i}", light)
        light_object.location = position
        scene.collection.objects.link(light_object)

    if out:
        scene.render.filepath = os.path.abspath(out)
        scene.render.image_settings.file_format = "PNG"


def main() -> None:
    args = common.parse_args(__doc__.splitlines()[0])
    import_ms, render_ms = [], []
    for run in range(args.repeat):
        with quiet_stdout():
            start = time.perf_counter()
            import_obj(args.obj)
            import_ms.append((time.perf_counter() - start) * 1000.0)
            out = args.out if run == args.repeat - 1 else None
            set_up(out)
            start = time.perf_counter()
            bpy.ops.render.render(write_still=bool(out))
            render_ms.append((time.perf_counter() - start) * 1000.0)
    triangles = sum(
        sum(len(p.vertices) - 2 for p in o.data.polygons)
        for o in bpy.context.scene.objects
        if o.type == "MESH"
    )
    common.emit(
        {
            "peer": "cycles",
            "version": f"bpy {bpy.app.version_string}",
            "triangles": triangles,
            "import_ms": common.ms(statistics.median(import_ms)),
            "render_ms": common.ms(statistics.median(render_ms)),
            "import_render_ms": common.ms(statistics.median(import_ms) + statistics.median(render_ms)),
        }
    )


if __name__ == "__main__":
    main()
