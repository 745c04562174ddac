//! One triangle or sphere against sixteen rays at once (SIMD across rays), for
//! packets and batches ([`crate::bvh::RayPacket`]). Each lane performs exactly the operations of
//! [`Triangle::intersect`] and of the four-lane packet kernel, in the same order and
//! without fused multiply-adds, so a lane's hit is bitwise the single-ray hit.

use wide::f32x16;

use super::lanes::moller_trumbore;
use super::{Sphere, Triangle};

/// Möller–Trumbore of `triangle` against the rays with origins `origin` and
/// directions `dir`: which lanes hit with `t > 0` (all-ones lanes; the caller compares
/// `t` with its own `t_max`), and each lane's `t`, `u`, `v`.
#[inline(always)]
pub fn triangle_across_rays(
    triangle: &Triangle,
    origin: &[f32x16; 3],
    dir: &[f32x16; 3],
) -> (f32x16, f32x16, f32x16, f32x16) {
    let splat = |v: crate::math::Vec3| v.to_array().map(f32x16::splat);
    moller_trumbore(
        *origin,
        *dir,
        splat(triangle.v0),
        splat(triangle.e1),
        splat(triangle.e2),
    )
}

/// [`Sphere::intersect`] of `sphere` against the rays with origins `origin` and
/// directions `dir` (unit length), lane by lane the same operations: which lanes hit
/// with `t > 0` (all-ones lanes; the caller compares `t` with its own `t_max`), and
/// each lane's `t`.
#[inline(always)]
pub fn sphere_across_rays(
    sphere: &Sphere,
    origin: &[f32x16; 3],
    dir: &[f32x16; 3],
) -> (f32x16, f32x16) {
    let [dx, dy, dz] = *dir;
    let ocx = origin[0] - f32x16::splat(sphere.center.x);
    let ocy = origin[1] - f32x16::splat(sphere.center.y);
    let ocz = origin[2] - f32x16::splat(sphere.center.z);
    let b = ocx * dx + ocy * dy + ocz * dz;
    let (px, py, pz) = (ocx - b * dx, ocy - b * dy, ocz - b * dz);
    let r2 = f32x16::splat(sphere.radius * sphere.radius);
    let root = (r2 - (px * px + py * py + pz * pz)).sqrt();
    let (near, far) = (-b - root, -b + root);
    let t = near.simd_gt(f32x16::ZERO).select(near, far);
    (t.simd_gt(f32x16::ZERO), t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::{Ray, Vec3};
    use rand::{Rng, SeedableRng};

    /// Every lane agrees bit for bit with the scalar kernel, hit or miss, on random
    /// triangles and rays aimed near them (many graze an edge).
    #[test]
    fn lanes_are_the_scalar_kernel() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let mut point = |scale: f32| {
            Vec3::new(
                rng.random_range(-scale..scale),
                rng.random_range(-scale..scale),
                rng.random_range(-scale..scale),
            )
        };
        let mut hits = 0;
        for _ in 0..2000 {
            let triangle = Triangle::new(point(3.0), point(3.0), point(3.0));
            let origin = point(10.0);
            let rays: Vec<Ray> = (0..16)
                .map(|_| {
                    let [a, b, c] = triangle.vertices();
                    let w = [point(1.0).x.abs(), point(1.0).x.abs(), point(1.0).x.abs()];
                    let target = (a * w[0] + b * w[1] + c * w[2]) / (w[0] + w[1] + w[2]);
                    Ray::new(origin + point(0.5), target - origin)
                })
                .collect();
            let lanes = |f: fn(&Ray) -> f32| f32x16::from(std::array::from_fn(|i| f(&rays[i])));
            let o = [
                lanes(|r| r.origin.x),
                lanes(|r| r.origin.y),
                lanes(|r| r.origin.z),
            ];
            let d = [lanes(|r| r.dir.x), lanes(|r| r.dir.y), lanes(|r| r.dir.z)];
            let (valid, t, u, v) = triangle_across_rays(&triangle, &o, &d);
            for (lane, ray) in rays.iter().enumerate() {
                let expected = triangle.intersect(ray, f32::INFINITY);
                let got = (valid.to_bitmask() >> lane & 1 == 1).then(|| {
                    (
                        t.as_array()[lane].to_bits(),
                        u.as_array()[lane].to_bits(),
                        v.as_array()[lane].to_bits(),
                    )
                });
                let expected = expected.map(|h| (h.t.to_bits(), h.u.to_bits(), h.v.to_bits()));
                assert_eq!(got, expected, "lane {lane}");
                hits += usize::from(got.is_some());
            }
        }
        assert!(hits > 10_000, "{hits} hits: the rays should mostly hit");
    }
}
