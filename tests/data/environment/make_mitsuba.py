#!/usr/bin/env python3
"""Mitsuba 3's image of a Lambertian sphere lit by the bundled HDR environment
(examples/environments/city.exr), for tests/environment.rs: an independent
renderer's answer for the environment's orientation, importance sampling and
lighting.

    pip install mitsuba
    python3 tests/data/environment/make_mitsuba.py

Writes tests/data/environment/mitsuba.exr (64 x 48, 4096 samples per pixel, linear).
Mitsuba's `envmap` puts the image's centre column elsewhere than three.js does (where
we follow three.js): turned by 90 degrees about +Y, as the issue says, it shows what
we show. (-90, 0 and 180 degrees differ from ours by 57-64% per pixel; 90 by the
noise alone.)
"""

import os

import mitsuba as mi

mi.set_variant("scalar_rgb")
HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(HERE)))
WIDTH, HEIGHT, FOV, SPP = 64, 48, 50, 4096
LOOK_FROM, LOOK_TO = [0.0, 0.5, 4.0], [0.0, 0.0, 0.0]


def main():
    scene = mi.load_dict({
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 8},
        "sensor": {
            "type": "perspective", "fov": FOV, "fov_axis": "y",
            "to_world": mi.ScalarTransform4f().look_at(origin=LOOK_FROM, target=LOOK_TO, up=[0, 1, 0]),
            "sampler": {"type": "independent", "sample_count": SPP},
            "film": {"type": "hdrfilm", "width": WIDTH, "height": HEIGHT,
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
        },
        "sphere": {"type": "sphere", "center": [0, 0, 0], "radius": 1.0,
                   "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.7, 0.7, 0.7]}}},
        "environment": {
            "type": "envmap",
            "filename": os.path.join(ROOT, "examples", "environments", "city.exr"),
            "to_world": mi.ScalarTransform4f().rotate(axis=[0, 1, 0], angle=90),
        },
    })
    image = mi.render(scene, spp=SPP)
    mi.Bitmap(image).write(os.path.join(HERE, "mitsuba.exr"))


if __name__ == "__main__":
    main()
