//! One triangle or sphere against sixteen rays at once (SIMD across rays), for
//! packets and batches ([`crate::bvh::RayPacket`]). Each lane performs exactly the operations of
//! [`Triangle::intersect`] and of the four-lane packet kernel, in the same order and
//! without fused multiply-adds, so a lane's hit is bitwise the single-ray hit.

use wide::f32x16;

use super::triangle::EDGE_SLACK;
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
    let splat = |v: f32| f32x16::splat(v);
    let [dx, dy, dz] = *dir;
    let (e1x, e1y, e1z) = (
        splat(triangle.e1.x),
        splat(triangle.e1.y),
        splat(triangle.e1.z),
    );
    let (e2x, e2y, e2z) = (
        splat(triangle.e2.x),
        splat(triangle.e2.y),
        splat(triangle.e2.z),
    );
    // p = dir x e2, as glam's `Vec3::cross`.
    let px = dy * e2z - e2y * dz;
    let py = dz * e2x - e2z * dx;
    let pz = dx * e2y - e2x * dy;
    let det = e1x * px + e1y * py + e1z * pz;
    let inv_det = f32x16::ONE / det;
    let sx = origin[0] - splat(triangle.v0.x);
    let sy = origin[1] - splat(triangle.v0.y);
    let sz = origin[2] - splat(triangle.v0.z);
    let u = (sx * px + sy * py + sz * pz) * inv_det;
    // q = s x e1.
    let qx = sy * e1z - e1y * sz;
    let qy = sz * e1x - e1z * sx;
    let qz = sx * e1y - e1x * sy;
    let v = (dx * qx + dy * qy + dz * qz) * inv_det;
    let t = (e2x * qx + e2y * qy + e2z * qz) * inv_det;
    let low = splat(-EDGE_SLACK);
    let high = splat(1.0 + EDGE_SLACK);
    let valid = det.simd_ne(f32x16::ZERO)
        & u.simd_ge(low)
        & u.simd_le(high)
        & v.simd_ge(low)
        & (u + v).simd_le(high)
        & t.simd_gt(f32x16::ZERO);
    (valid, t, u, v)
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
