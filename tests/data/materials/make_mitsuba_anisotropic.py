#!/usr/bin/env python3
"""Mitsuba 3's anisotropic `roughconductor` (GGX, `alpha_u` along the shading frame's
`s`, `alpha_v` along `t`; `material = "none"`: a perfect conductor, Fresnel 1)
evaluated at fixed pairs of directions, for tests/anisotropy.rs, which compares our
anisotropic GGX with Mitsuba's separable Smith term swapped in (Mitsuba's default;
glTF's is height-correlated).

    pip install mitsuba
    python3 tests/data/materials/make_mitsuba_anisotropic.py > tests/data/materials/roughconductor_anisotropic.toml

Mitsuba's `eval` returns `f * cos(wo)`; the file holds `f`.
"""

import math

import mitsuba as mi

mi.set_variant("scalar_rgb")


def direction(theta_degrees, phi_degrees):
    t, p = math.radians(theta_degrees), math.radians(phi_degrees)
    return [math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)]


def main():
    print(f"# Written by make_mitsuba_anisotropic.py with Mitsuba {mi.__version__} (scalar_rgb).")
    for alpha_u, alpha_v in [(0.6, 0.15), (0.1, 0.5), (0.73, 0.25)]:
        bsdf = mi.load_dict({"type": "roughconductor", "distribution": "ggx",
                             "alpha_u": alpha_u, "alpha_v": alpha_v, "material": "none"})
        ctx = mi.BSDFContext()
        for theta_i, phi_i in [(0, 0), (30, 0), (60, 90), (45, 30), (80, 200)]:
            for theta_o, phi_o in [(0, 0), (20, 180), (45, 180), (45, 90), (30, 270), (70, 200), (85, 10)]:
                wi, wo = direction(theta_i, phi_i), direction(theta_o, phi_o)
                si = mi.SurfaceInteraction3f()
                si.sh_frame = mi.Frame3f(mi.Vector3f(1, 0, 0), mi.Vector3f(0, 1, 0), mi.Vector3f(0, 0, 1))
                si.wi = mi.Vector3f(wi)
                value = bsdf.eval(ctx, si, mi.Vector3f(wo))[0] / wo[2]
                print("[[pair]]")
                print(f"alpha_u = {alpha_u}")
                print(f"alpha_v = {alpha_v}")
                print(f"wi = [{wi[0]!r}, {wi[1]!r}, {wi[2]!r}]")
                print(f"wo = [{wo[0]!r}, {wo[1]!r}, {wo[2]!r}]")
                print(f"f = {value!r}")


if __name__ == "__main__":
    main()
