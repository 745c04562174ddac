#!/usr/bin/env python3
"""Mitsuba 3's `roughconductor` (GGX, `material = "none"`: a perfect conductor, so
Fresnel 1, as glTF's metal of white base colour) evaluated at fixed pairs of
directions, for tests/materials.rs, which compares our GGX lobe with Mitsuba's
separable Smith term swapped in (Mitsuba's default; glTF's is height-correlated).

    pip install mitsuba
    python3 tests/data/materials/make_mitsuba.py > tests/data/materials/roughconductor.toml

Mitsuba's `eval` returns `f * cos(wo)`; the file holds `f`.
"""

import math

import mitsuba as mi

mi.set_variant("scalar_rgb")


def direction(theta_degrees, phi_degrees):
    t, p = math.radians(theta_degrees), math.radians(phi_degrees)
    return [math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)]


def main():
    print(f"# Written by make_mitsuba.py with Mitsuba {mi.__version__} (scalar_rgb).")
    for alpha in [0.05, 0.2, 0.5, 0.9]:
        bsdf = mi.load_dict({"type": "roughconductor", "distribution": "ggx",
                             "alpha": alpha, "material": "none"})
        ctx = mi.BSDFContext()
        for theta_i in [0, 30, 60, 80]:
            for theta_o, phi_o in [(0, 0), (20, 180), (45, 180), (45, 90), (70, 200), (85, 10)]:
                wi, wo = direction(theta_i, 0), direction(theta_o, phi_o)
                si = mi.SurfaceInteraction3f()
                si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
                si.wi = mi.Vector3f(wi)
                value = bsdf.eval(ctx, si, mi.Vector3f(wo))[0] / wo[2]
                print("[[pair]]")
                print(f"alpha = {alpha}")
                print(f"wi = [{wi[0]!r}, {wi[1]!r}, {wi[2]!r}]")
                print(f"wo = [{wo[0]!r}, {wo[1]!r}, {wo[2]!r}]")
                print(f"f = {value!r}")


if __name__ == "__main__":
    main()
