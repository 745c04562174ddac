//! Four triangles in structure-of-arrays form, intersected with one ray at once by a
//! 4-lane Möller–Trumbore (the leaf layout of Embree's `Triangle4` and tinybvh's
//! SIMD leaves).
//!
//! Each lane computes exactly what [`Triangle::intersect`] computes, operation for
//! operation (no fused multiply-adds), so a packet finds the same hits, bit for bit,
//! as the scalar kernel run over its triangles in lane order.

use wide::f32x4;

use super::{PrimHit, Triangle};
use crate::math::{Float, Ray};

use super::triangle::EDGE_SLACK;

/// Lanes per packet.
pub const LANES: usize = 4;

/// Up to four triangles, each lane holding one triangle's vertex 0 and two edges, and
/// the primitive it stands for. Unused lanes hold a zero triangle (zero determinant for
/// every ray), so they never hit.
#[derive(Clone, Copy, Debug)]
#[repr(C)]
pub struct TrianglePacket {
    v0: [f32x4; 3],
    e1: [f32x4; 3],
    e2: [f32x4; 3],
    /// Primitive index (leaf order) of each lane; unused lanes repeat lane 0's.
    pub prims: [u32; LANES],
}

/// A ray with each component splatted over four lanes, prepared once per ray.
#[derive(Clone, Copy, Debug)]
pub struct PacketRay {
    origin: [f32x4; 3],
    dir: [f32x4; 3],
}

impl PacketRay {
    /// Prepares `ray` for packet tests.
    #[inline(always)]
    pub fn new(ray: &Ray) -> PacketRay {
        let o = ray.origin.to_array();
        let d = ray.dir.to_array();
        PacketRay {
            origin: o.map(f32x4::splat),
            dir: d.map(f32x4::splat),
        }
    }
}

impl TrianglePacket {
    /// A packet of one to four `(primitive, triangle)` pairs.
    ///
    /// # Panics
    /// If `triangles` is empty or holds more than [`LANES`] entries.
    pub fn new(triangles: &[(u32, Triangle)]) -> TrianglePacket {
        assert!((1..=LANES).contains(&triangles.len()), "1 to 4 triangles");
        let mut lanes = [[[0.0 as Float; LANES]; 3]; 3];
        let mut prims = [triangles[0].0; LANES];
        for (lane, &(prim, tri)) in triangles.iter().enumerate() {
            prims[lane] = prim;
            for (vector, value) in lanes.iter_mut().zip([tri.v0, tri.e1, tri.e2]) {
                for axis in 0..3 {
                    vector[axis][lane] = value[axis];
                }
            }
        }
        let [v0, e1, e2] = lanes.map(|v| v.map(f32x4::from));
        TrianglePacket { v0, e1, e2, prims }
    }

    /// The nearest hit with `0 < t < t_max` among the lanes, as `(lane, hit)`; on equal
    /// distances the lowest lane wins, as it would in a scalar loop.
    #[inline(always)]
    pub fn intersect(&self, ray: &PacketRay, t_max: Float) -> Option<(usize, PrimHit)> {
        let (valid, t, u, v) = self.lanes(ray, t_max);
        let mut mask = valid.to_bitmask();
        if mask == 0 {
            return None;
        }
        let (t, u, v) = (t.as_array(), u.as_array(), v.as_array());
        let mut best = mask.trailing_zeros() as usize;
        mask &= mask - 1;
        while mask != 0 {
            let lane = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            if t[lane] < t[best] {
                best = lane;
            }
        }
        Some((
            best,
            PrimHit {
                t: t[best],
                u: u[best],
                v: v[best],
            },
        ))
    }

    /// Whether any lane is hit with `0 < t < t_max`.
    #[inline(always)]
    pub fn occludes(&self, ray: &PacketRay, t_max: Float) -> bool {
        self.lanes(ray, t_max).0.any()
    }

    /// Möller–Trumbore on all lanes: which lanes hit, and their `t`, `u`, `v`.
    #[inline(always)]
    fn lanes(&self, ray: &PacketRay, t_max: Float) -> (f32x4, f32x4, f32x4, f32x4) {
        let [dx, dy, dz] = ray.dir;
        let [e1x, e1y, e1z] = self.e1;
        let [e2x, e2y, e2z] = self.e2;
        // p = dir x e2, as glam's `Vec3::cross`.
        let px = dy * e2z - e2y * dz;
        let py = dz * e2x - e2z * dx;
        let pz = dx * e2y - e2x * dy;
        let det = e1x * px + e1y * py + e1z * pz;
        let inv_det = f32x4::ONE / det;
        let sx = ray.origin[0] - self.v0[0];
        let sy = ray.origin[1] - self.v0[1];
        let sz = ray.origin[2] - self.v0[2];
        let u = (sx * px + sy * py + sz * pz) * inv_det;
        // q = s x e1.
        let qx = sy * e1z - e1y * sz;
        let qy = sz * e1x - e1z * sx;
        let qz = sx * e1y - e1x * sy;
        let v = (dx * qx + dy * qy + dz * qz) * inv_det;
        let t = (e2x * qx + e2y * qy + e2z * qz) * inv_det;
        let low = f32x4::splat(-EDGE_SLACK);
        let high = f32x4::splat(1.0 + EDGE_SLACK);
        let valid = det.simd_ne(f32x4::ZERO)
            & u.simd_ge(low)
            & u.simd_le(high)
            & v.simd_ge(low)
            & (u + v).simd_le(high)
            & t.simd_gt(f32x4::ZERO)
            & t.simd_lt(f32x4::splat(t_max));
        (valid, t, u, v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;
    use rand::{Rng, SeedableRng};

    fn random_vec(rng: &mut rand::rngs::StdRng, scale: f32) -> Vec3 {
        Vec3::new(
            rng.random_range(-scale..scale),
            rng.random_range(-scale..scale),
            rng.random_range(-scale..scale),
        )
    }

    /// The scalar kernel over the same triangles in lane order, keeping a hit only
    /// when strictly closer: what a packet must reproduce bit for bit.
    fn scalar_nearest(
        tris: &[(u32, Triangle)],
        ray: &Ray,
        t_max: Float,
    ) -> Option<(usize, PrimHit)> {
        let mut t_max = t_max;
        let mut nearest = None;
        for (lane, (_, tri)) in tris.iter().enumerate() {
            if let Some(hit) = tri.intersect(ray, t_max) {
                t_max = hit.t;
                nearest = Some((lane, hit));
            }
        }
        nearest
    }

    #[test]
    fn packet_equals_scalar_kernel_bit_for_bit() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(11);
        let mut hits = 0;
        for case in 0..20_000 {
            let lanes = 1 + case % LANES;
            // Small triangles near the origin, some sharing an edge or a vertex, so
            // that edge hits and ties between lanes occur.
            let shared = random_vec(&mut rng, 1.0);
            let tris: Vec<(u32, Triangle)> = (0..lanes)
                .map(|i| {
                    let a = if i % 2 == 0 {
                        shared
                    } else {
                        random_vec(&mut rng, 1.0)
                    };
                    let tri =
                        Triangle::new(a, random_vec(&mut rng, 1.0), random_vec(&mut rng, 1.0));
                    (100 + i as u32, tri)
                })
                .collect();
            let packet = TrianglePacket::new(&tris);
            let origin = random_vec(&mut rng, 3.0);
            let target = if case % 3 == 0 {
                shared
            } else {
                random_vec(&mut rng, 1.0)
            };
            let ray = Ray::new(origin, (target - origin).normalize());
            let t_max = if case % 5 == 0 {
                rng.random_range(0.5..4.0)
            } else {
                Float::INFINITY
            };
            let expected = scalar_nearest(&tris, &ray, t_max);
            let got = packet.intersect(&PacketRay::new(&ray), t_max);
            assert_eq!(got, expected, "case {case}: {tris:?} {ray:?}");
            assert_eq!(
                packet.occludes(&PacketRay::new(&ray), t_max),
                expected.is_some()
            );
            if let Some((lane, _)) = got {
                assert_eq!(packet.prims[lane], tris[lane].0);
                hits += 1;
            }
        }
        assert!(hits > 2_000, "too few hits ({hits}) to mean anything");
    }

    #[test]
    fn unused_lanes_never_hit() {
        let tri = Triangle::new(
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        );
        let packet = TrianglePacket::new(&[(7, tri)]);
        assert_eq!(packet.prims, [7; LANES]);
        // A ray through the origin (where the zero triangles of unused lanes sit) in
        // every direction hits lane 0 or nothing.
        for dir in [
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            Vec3::new(0.3, 0.2, -1.0).normalize(),
        ] {
            let ray = Ray::new(-dir * 2.0, dir);
            if let Some((lane, _)) = packet.intersect(&PacketRay::new(&ray), Float::INFINITY) {
                assert_eq!(lane, 0);
            }
        }
    }
}
