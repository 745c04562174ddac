#!/usr/bin/env python3
"""Makes the DWA fixtures of tests/environment.rs with the reference OpenEXR library
(`pip install OpenEXR`, 3.x), not with this renderer:

- map-dwaa.exr, map-dwab.exr: a 96x48 half-float RGB map (a sky-like gradient, a
  small bright sun and a little noise, so that the lossy DCT blocks, their
  run-length coded coefficients and values above 1 are all exercised), compressed
  with DWAA and DWAB as HDRI packages ship them (drei's environment presets are
  DWAB);
- map-dwaa-decoded.exr, map-dwab-decoded.exr: what OpenEXR itself decodes from each,
  written again with lossless ZIP compression: the independent answer the renderer's
  reading of the DWA files must equal texel for texel.

    python3 tests/data/environment/dwa/make_dwa.py
"""

import os

import numpy as np
import OpenEXR

HERE = os.path.dirname(os.path.abspath(__file__))
WIDTH, HEIGHT = 96, 48


def texels():
    rng = np.random.default_rng(7)
    y, x = np.mgrid[0:HEIGHT, 0:WIDTH].astype(np.float32)
    v = 1.0 - (y + 0.5) / HEIGHT
    sky = np.stack([0.3 + 0.5 * v, 0.4 + 0.5 * v, 0.6 + 0.8 * v], axis=-1)
    sun = 40.0 * np.exp(-(((x - 30) ** 2 + (y - 12) ** 2) / 4.0))[..., None]
    noise = 0.05 * rng.standard_normal((HEIGHT, WIDTH, 3)).astype(np.float32)
    return (sky + sun + noise).astype(np.float16)


def write(path, pixels, compression):
    header = {"compression": compression, "type": OpenEXR.scanlineimage}
    OpenEXR.File(header, {"RGB": pixels}).write(path)


def main():
    pixels = texels()
    for name, compression in (("dwaa", OpenEXR.DWAA_COMPRESSION), ("dwab", OpenEXR.DWAB_COMPRESSION)):
        path = os.path.join(HERE, f"map-{name}.exr")
        write(path, pixels, compression)
        decoded = OpenEXR.File(path).channels()["RGB"].pixels
        assert decoded.dtype == np.float16
        write(os.path.join(HERE, f"map-{name}-decoded.exr"), decoded, OpenEXR.ZIP_COMPRESSION)
        print(path, "differs from its input in", int((decoded != pixels).any(axis=-1).sum()), "texels")


if __name__ == "__main__":
    main()
