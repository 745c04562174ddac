#!/usr/bin/env python3
"""Mitsuba 3's `roughconductor` (GGX, `material = "none"`: a perfect conductor, so
Fresnel 1, as glTF's metal of white base colour) evaluated at fixed pairs of
directions, for the tests that compare our GGX with Mitsuba's separable Smith term
swapped in (Mitsuba's default; glTF's is height-correlated): isotropic for
tests/materials.rs, and with `--anisotropic` (`alpha_u` along the shading frame's
`s`, `alpha_v` along `t`) for tests/anisotropy.rs.

    pip install mitsuba
    python3 tests/data/materials/make_mitsuba.py > tests/data/materials/roughconductor.toml
    python3 tests/data/materials/make_mitsuba.py --anisotropic > tests/data/materials/roughconductor_anisotropic.toml

Mitsuba's `eval` returns `f * cos(wo)`; the file holds `f`.
"""

import math
import sys

import mitsuba as mi

mi.set_variant("scalar_rgb")

# (the table's keys and values of each distribution, the incident directions, the
# outgoing directions), as (theta, phi) in degrees.
ISOTROPIC = (
    [{"alpha": a} for a in [0.05, 0.2, 0.5, 0.9]],
    [(t, 0) for t in [0, 30, 60, 80]],
    [(0, 0), (20, 180), (45, 180), (45, 90), (70, 200), (85, 10)],
)
ANISOTROPIC = (
    [{"alpha_u": u, "alpha_v": v} for u, v in [(0.6, 0.15), (0.1, 0.5), (0.73, 0.25)]],
    [(0, 0), (30, 0), (60, 90), (45, 30), (80, 200)],
    [(0, 0), (20, 180), (45, 180), (45, 90), (30, 270), (70, 200), (85, 10)],
)


def direction(theta_degrees, phi_degrees):
    t, p = math.radians(theta_degrees), math.radians(phi_degrees)
    return [math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)]


def main():
    anisotropic = "--anisotropic" in sys.argv[1:]
    alphas, incident, outgoing = ANISOTROPIC if anisotropic else ISOTROPIC
    flag = " --anisotropic" if anisotropic else ""
    print(f"# Written by make_mitsuba.py{flag} with Mitsuba {mi.__version__} (scalar_rgb).")
    for alpha in alphas:
        bsdf = mi.load_dict({"type": "roughconductor", "distribution": "ggx",
                             **alpha, "material": "none"})
        ctx = mi.BSDFContext()
        for theta_i, phi_i in incident:
            for theta_o, phi_o in outgoing:
                wi, wo = direction(theta_i, phi_i), direction(theta_o, phi_o)
                si = mi.SurfaceInteraction3f()
                si.sh_frame = mi.Frame3f(mi.Vector3f(1, 0, 0), mi.Vector3f(0, 1, 0), mi.Vector3f(0, 0, 1))
                si.wi = mi.Vector3f(wi)
                value = bsdf.eval(ctx, si, mi.Vector3f(wo))[0] / wo[2]
                print("[[pair]]")
                for key, number in alpha.items():
                    print(f"{key} = {number}")
                print(f"wi = [{wi[0]!r}, {wi[1]!r}, {wi[2]!r}]")
                print(f"wo = [{wo[0]!r}, {wo[1]!r}, {wo[2]!r}]")
                print(f"f = {value!r}")


if __name__ == "__main__":
    main()
