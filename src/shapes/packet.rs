//! Four triangles in structure-of-arrays form, intersected with one ray at once by a
//! 4-lane Möller–Trumbore (the leaf layout of Embree's `Triangle4` and tinybvh's
//! SIMD leaves). A packet may instead hold up to four spheres, tested one by one:
//! packets are the only copy of the scene's geometry.
//!
//! Each lane computes exactly what [`Triangle::intersect`] computes, operation for
//! operation (no fused multiply-adds), so a packet finds the same hits, bit for bit,
//! as the scalar kernel run over its triangles in lane order.

use wide::{f32x4, f32x8};

use super::{PrimHit, Shape, Sphere, Triangle};
use crate::math::{Float, Ray, Vec3, nearest_in_mask};

use super::lanes::moller_trumbore;

/// Lanes per packet.
pub const LANES: usize = 4;

/// Flag on the primitive indices of a packet of spheres.
const SPHERE_FLAG: u32 = 1 << 31;
/// The primitive index of an unused lane.
const UNUSED: u32 = u32::MAX;
/// Largest primitive index a packet can hold.
pub const MAX_PRIM: u32 = SPHERE_FLAG - 2;

/// Up to four triangles, each lane holding one triangle's vertex 0 and two edges, and
/// the primitive it stands for; or up to four spheres, each lane holding a centre in
/// `v0` and a radius in `e1`'s x. Unused lanes hold a zero triangle (zero determinant
/// for every ray) or a sphere of NaN radius, so they never hit. 160 bytes.
#[derive(Clone, Copy, Debug)]
#[repr(C)]
pub struct TrianglePacket {
    v0: [f32x4; 3],
    e1: [f32x4; 3],
    e2: [f32x4; 3],
    /// Primitive index (leaf order) of each lane, [`SPHERE_FLAG`] set in a sphere
    /// packet; [`UNUSED`] for an unused lane.
    prims: [u32; LANES],
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
    /// Also if a primitive index exceeds [`MAX_PRIM`].
    pub fn new(triangles: &[(u32, Triangle)]) -> TrianglePacket {
        let lanes = triangles
            .iter()
            .map(|&(prim, tri)| (prim, [tri.v0, tri.e1, tri.e2]));
        TrianglePacket::from_lanes(lanes, 0)
    }

    /// A packet of one to four `(primitive, sphere)` pairs.
    ///
    /// # Panics
    /// As [`TrianglePacket::new`].
    pub fn spheres(spheres: &[(u32, Sphere)]) -> TrianglePacket {
        let lanes = spheres
            .iter()
            .map(|&(prim, s)| (prim, [s.center, Vec3::new(s.radius, 0.0, 0.0), Vec3::ZERO]));
        let mut packet = TrianglePacket::from_lanes(lanes, SPHERE_FLAG);
        // A NaN radius makes every test of an unused lane fail, so that the lanes
        // need no mask (a zero radius would still meet a ray through the origin).
        for lane in spheres.len()..LANES {
            packet.e1[0].as_mut_array()[lane] = Float::NAN;
        }
        packet
    }

    fn from_lanes<I>(values: I, flag: u32) -> TrianglePacket
    where
        I: ExactSizeIterator<Item = (u32, [Vec3; 3])>,
    {
        assert!((1..=LANES).contains(&values.len()), "1 to 4 shapes");
        let mut lanes = [[[0.0 as Float; LANES]; 3]; 3];
        let mut prims = [UNUSED; LANES];
        for (lane, (prim, vectors)) in values.enumerate() {
            assert!(
                prim <= MAX_PRIM,
                "primitive index {prim} too large for a packet"
            );
            prims[lane] = prim | flag;
            for (vector, value) in lanes.iter_mut().zip(vectors) {
                for axis in 0..3 {
                    vector[axis][lane] = value[axis];
                }
            }
        }
        let [v0, e1, e2] = lanes.map(|v| v.map(f32x4::from));
        TrianglePacket { v0, e1, e2, prims }
    }

    /// Whether the packet holds spheres rather than triangles.
    #[inline(always)]
    pub fn holds_spheres(&self) -> bool {
        self.prims[0] & SPHERE_FLAG != 0
    }

    /// The primitive in `lane` (leaf order), if the lane is used.
    #[inline(always)]
    pub fn prim(&self, lane: usize) -> Option<u32> {
        match self.prims[lane] {
            UNUSED => None,
            prim => Some(prim & !SPHERE_FLAG),
        }
    }

    /// The shape in `lane`, if the lane is used: exactly the values it was made from.
    pub fn shape(&self, lane: usize) -> Option<Shape> {
        self.prim(lane)?;
        let vector = |v: &[f32x4; 3]| {
            Vec3::new(
                v[0].as_array()[lane],
                v[1].as_array()[lane],
                v[2].as_array()[lane],
            )
        };
        let (v0, e1) = (vector(&self.v0), vector(&self.e1));
        Some(if self.holds_spheres() {
            Shape::Sphere(Sphere {
                center: v0,
                radius: e1.x,
            })
        } else {
            Shape::Triangle(Triangle {
                v0,
                e1,
                e2: vector(&self.e2),
            })
        })
    }

    /// The nearest hit with `0 < t < t_max` in the packet, as `(lane, hit)`: all
    /// triangle lanes at once, or each sphere in turn.
    #[inline(always)]
    pub fn intersect_any_kind(&self, lanes: &PacketRay, t_max: Float) -> Option<(usize, PrimHit)> {
        if !self.holds_spheres() {
            return self.intersect(lanes, t_max);
        }
        self.intersect_spheres(lanes, t_max)
    }

    /// Whether any lane is hit with `0 < t < t_max`, whatever the packet holds.
    #[inline(always)]
    pub fn occludes_any_kind(&self, lanes: &PacketRay, t_max: Float) -> bool {
        if !self.holds_spheres() {
            return self.occludes(lanes, t_max);
        }
        self.sphere_lanes(lanes, t_max).0.any()
    }

    /// The nearest hit with `0 < t < t_max` among the lanes of a sphere packet, as
    /// `(lane, hit)`: all lanes at once, each computing exactly what
    /// [`Sphere::intersect`] computes (so the same hits, bit for bit), and the lowest
    /// lane winning on equal distances, as in a scalar loop over the lanes.
    #[inline(always)]
    fn intersect_spheres(&self, ray: &PacketRay, t_max: Float) -> Option<(usize, PrimHit)> {
        let (valid, t) = self.sphere_lanes(ray, t_max);
        let lane = nearest_in_mask(valid.to_bitmask(), &t.to_array())?;
        Some((
            lane,
            PrimHit {
                t: t.as_array()[lane],
                u: 0.0,
                v: 0.0,
            },
        ))
    }

    /// [`Sphere::intersect`] on all lanes: which lanes hit, and their `t`. A negative
    /// discriminant gives a NaN root and so a NaN `t`, which fails both tests, as
    /// does the NaN radius of an unused lane.
    #[inline(always)]
    fn sphere_lanes(&self, ray: &PacketRay, t_max: Float) -> (f32x4, f32x4) {
        let [dx, dy, dz] = ray.dir;
        let ocx = ray.origin[0] - self.v0[0];
        let ocy = ray.origin[1] - self.v0[1];
        let ocz = ray.origin[2] - self.v0[2];
        let b = ocx * dx + ocy * dy + ocz * dz;
        let (px, py, pz) = (ocx - b * dx, ocy - b * dy, ocz - b * dz);
        let radius = self.e1[0];
        let discriminant = radius * radius - (px * px + py * py + pz * pz);
        let root = discriminant.sqrt();
        let (near, far) = (-b - root, -b + root);
        let t = near.simd_gt(f32x4::ZERO).select(near, far);
        let valid = t.simd_gt(f32x4::ZERO) & t.simd_lt(f32x4::splat(t_max));
        (valid, t)
    }

    /// The nearest hit with `0 < t < t_max` among the lanes of a triangle packet, as
    /// `(lane, hit)`; on equal distances the lowest lane wins, as it would in a scalar
    /// loop.
    #[inline(always)]
    pub fn intersect(&self, ray: &PacketRay, t_max: Float) -> Option<(usize, PrimHit)> {
        let (valid, t, u, v) = self.lanes(ray, t_max);
        nearest_hit(valid.to_bitmask(), t.as_array(), u.as_array(), v.as_array())
    }

    /// Every lane of a triangle packet hit with `0 < t < t_max`: a bit mask of the
    /// lanes, and each lane's `t`, `u`, `v` (meaningless where its bit is clear). For
    /// queries that must look past the nearest hit, such as alpha cutouts.
    #[inline(always)]
    pub fn hits(&self, ray: &PacketRay, t_max: Float) -> (u32, [Float; 4], [Float; 4], [Float; 4]) {
        let (valid, t, u, v) = self.lanes(ray, t_max);
        (valid.to_bitmask(), t.to_array(), u.to_array(), v.to_array())
    }

    /// Whether any lane of a triangle packet is hit with `0 < t < t_max`.
    #[inline(always)]
    pub fn occludes(&self, ray: &PacketRay, t_max: Float) -> bool {
        self.lanes(ray, t_max).0.any()
    }

    /// [`TrianglePacket::intersect`] over two triangle packets at once, lanes 0-3
    /// being `first`'s and 4-7 `second`'s: the nearest hit with `0 < t < t_max`,
    /// the lowest lane winning on equal distances, which is what `intersect` on
    /// `first`, then on `second` below the first's hit, finds.
    #[inline(always)]
    pub fn intersect_pair(
        first: &TrianglePacket,
        second: &TrianglePacket,
        ray: &PacketRay,
        t_max: Float,
    ) -> Option<(usize, PrimHit)> {
        let (valid, t, u, v) = TrianglePacket::hits_pair(first, second, ray, t_max);
        nearest_hit(valid, &t, &u, &v)
    }

    /// [`TrianglePacket::hits`] over two triangle packets at once, lanes 0-3 being
    /// `first`'s and 4-7 `second`'s: one eight-lane Möller–Trumbore (AVX) rather
    /// than two of four, since most leaves of a big mesh hold two packets (the
    /// dragon's bounce rays: 1.08x). Each lane's results are bit for bit those of
    /// its packet's own test.
    #[inline(always)]
    pub fn hits_pair(
        first: &TrianglePacket,
        second: &TrianglePacket,
        ray: &PacketRay,
        t_max: Float,
    ) -> (u32, [Float; 8], [Float; 8], [Float; 8]) {
        let join = |a: f32x4, b: f32x4| {
            let (a, b) = (a.to_array(), b.to_array());
            f32x8::new([a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3]])
        };
        let splat = |a: f32x4| f32x8::splat(a.as_array()[0]);
        let (valid, t, u, v) = moller_trumbore(
            ray.origin.map(splat),
            ray.dir.map(splat),
            [0, 1, 2].map(|k| join(first.v0[k], second.v0[k])),
            [0, 1, 2].map(|k| join(first.e1[k], second.e1[k])),
            [0, 1, 2].map(|k| join(first.e2[k], second.e2[k])),
        );
        let valid = valid & t.simd_lt(f32x8::splat(t_max));
        (valid.to_bitmask(), t.to_array(), u.to_array(), v.to_array())
    }

    /// Möller–Trumbore on all lanes: which lanes hit, and their `t`, `u`, `v`.
    #[inline(always)]
    fn lanes(&self, ray: &PacketRay, t_max: Float) -> (f32x4, f32x4, f32x4, f32x4) {
        let (valid, t, u, v) = moller_trumbore(ray.origin, ray.dir, self.v0, self.e1, self.e2);
        (valid & t.simd_lt(f32x4::splat(t_max)), t, u, v)
    }
}

/// The nearest of the lanes in `mask` as `(lane, hit)`, the lowest lane winning on
/// equal distances, as in a scalar loop over the lanes.
#[inline(always)]
fn nearest_hit<const N: usize>(
    mask: u32,
    t: &[Float; N],
    u: &[Float; N],
    v: &[Float; N],
) -> Option<(usize, PrimHit)> {
    let best = nearest_in_mask(mask, t)?;
    Some((
        best,
        PrimHit {
            t: t[best],
            u: u[best],
            v: v[best],
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// `lanes` random triangles near the origin, numbered from `first_prim`, every
    /// other one with a corner at `shared`.
    fn random_triangles(
        rng: &mut rand::rngs::StdRng,
        lanes: usize,
        shared: Vec3,
        first_prim: u32,
    ) -> Vec<(u32, Triangle)> {
        (0..lanes)
            .map(|i| {
                let a = if i % 2 == 0 {
                    shared
                } else {
                    random_vec(rng, 1.0)
                };
                let tri = Triangle::new(a, random_vec(rng, 1.0), random_vec(rng, 1.0));
                (first_prim + i as u32, tri)
            })
            .collect()
    }

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

    /// Two packets in one eight-lane test find what testing the first, then the
    /// second below the first's hit, finds; and each half of the lanes holds its
    /// packet's own hits, bit for bit.
    #[test]
    fn packet_pairs_equal_two_packets_in_turn_bit_for_bit() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(12);
        let mut hits = [0; 2];
        for case in 0..20_000 {
            let shared = random_vec(&mut rng, 1.0);
            let first_tris = random_triangles(&mut rng, 1 + case % LANES, shared, 0);
            let mut second_tris = random_triangles(&mut rng, 1 + (case / 4) % LANES, shared, 10);
            // Sometimes a copy of the first packet's triangle: a tie between them.
            if case % 7 == 0 {
                second_tris[0].1 = first_tris[0].1;
            }
            let (first, second) = (
                TrianglePacket::new(&first_tris),
                TrianglePacket::new(&second_tris),
            );
            let origin = random_vec(&mut rng, 3.0);
            let target = if case % 3 == 0 {
                shared
            } else {
                random_vec(&mut rng, 1.0)
            };
            let ray = PacketRay::new(&Ray::new(origin, (target - origin).normalize()));
            let t_max = if case % 5 == 0 {
                rng.random_range(0.5..4.0)
            } else {
                Float::INFINITY
            };
            let in_turn = match first.intersect(&ray, t_max) {
                Some((lane, hit)) => match second.intersect(&ray, hit.t) {
                    Some((lane, hit)) => Some((LANES + lane, hit)),
                    None => Some((lane, hit)),
                },
                None => second
                    .intersect(&ray, t_max)
                    .map(|(lane, hit)| (LANES + lane, hit)),
            };
            let got = TrianglePacket::intersect_pair(&first, &second, &ray, t_max);
            assert_eq!(got, in_turn, "case {case}");
            if let Some((lane, _)) = got {
                hits[lane / LANES] += 1;
            }
            let (mask, t, u, v) = TrianglePacket::hits_pair(&first, &second, &ray, t_max);
            for (half, packet) in [first, second].iter().enumerate() {
                let (own_mask, own_t, own_u, own_v) = packet.hits(&ray, t_max);
                assert_eq!((mask >> (LANES * half)) & 0xf, own_mask, "case {case}");
                for lane in 0..LANES {
                    if own_mask >> lane & 1 != 0 {
                        let pair_lane = LANES * half + lane;
                        assert_eq!(t[pair_lane].to_bits(), own_t[lane].to_bits());
                        assert_eq!(u[pair_lane].to_bits(), own_u[lane].to_bits());
                        assert_eq!(v[pair_lane].to_bits(), own_v[lane].to_bits());
                    }
                }
            }
        }
        assert!(hits.iter().all(|&h| h > 1_000), "too few hits: {hits:?}");
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
            let tris = random_triangles(&mut rng, lanes, shared, 100);
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
                assert_eq!(packet.prim(lane), Some(tris[lane].0));
                hits += 1;
            }
            for (lane, &(prim, tri)) in tris.iter().enumerate() {
                assert_eq!(packet.prim(lane), Some(prim));
                assert_eq!(packet.shape(lane), Some(Shape::Triangle(tri)));
            }
            assert!(!packet.holds_spheres());
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
        assert_eq!(packet.prim(0), Some(7));
        assert!((1..LANES).all(|lane| packet.prim(lane).is_none() && packet.shape(lane).is_none()));
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

#[cfg(test)]
mod sphere_tests {
    use super::*;

    #[test]
    fn sphere_packets_keep_their_spheres_and_hit_like_the_scalar_kernel() {
        let spheres = [
            (
                3,
                Sphere {
                    center: Vec3::new(0.0, 0.0, -5.0),
                    radius: 1.0,
                },
            ),
            (
                MAX_PRIM,
                Sphere {
                    center: Vec3::new(0.0, 0.0, -3.0),
                    radius: 0.5,
                },
            ),
        ];
        let packet = TrianglePacket::spheres(&spheres);
        assert!(packet.holds_spheres());
        for (lane, &(prim, sphere)) in spheres.iter().enumerate() {
            assert_eq!(packet.prim(lane), Some(prim));
            assert_eq!(packet.shape(lane), Some(Shape::Sphere(sphere)));
        }
        assert_eq!(packet.prim(2), None);
        let ray = Ray::new(Vec3::ZERO, Vec3::NEG_Z);
        let (lane, hit) = packet
            .intersect_any_kind(&PacketRay::new(&ray), Float::INFINITY)
            .unwrap();
        assert_eq!(lane, 1);
        assert_eq!(Some(hit), spheres[1].1.intersect(&ray, Float::INFINITY));
        assert_eq!(packet.intersect_any_kind(&PacketRay::new(&ray), 2.0), None);
    }

    /// The scalar kernel over the same spheres in lane order, keeping a hit only when
    /// strictly closer: what a sphere packet must reproduce bit for bit.
    fn scalar_nearest(
        spheres: &[(u32, Sphere)],
        ray: &Ray,
        t_max: Float,
    ) -> Option<(usize, PrimHit)> {
        let mut t_max = t_max;
        let mut nearest = None;
        for (lane, (_, sphere)) in spheres.iter().enumerate() {
            if let Some(hit) = sphere.intersect(ray, t_max) {
                t_max = hit.t;
                nearest = Some((lane, hit));
            }
        }
        nearest
    }

    #[test]
    fn sphere_packets_equal_the_scalar_kernel_bit_for_bit() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(12);
        let coordinate = |rng: &mut rand::rngs::StdRng, scale: Float| {
            Vec3::new(
                rng.random_range(-scale..scale),
                rng.random_range(-scale..scale),
                rng.random_range(-scale..scale),
            )
        };
        let (mut hits, mut inside) = (0, 0);
        for case in 0..20_000 {
            let lanes = 1 + case % LANES;
            // Some spheres repeated, so that equal distances occur; some around the
            // origin, where the unused lanes' centres sit.
            let first = Sphere {
                center: coordinate(&mut rng, 2.0),
                radius: rng.random_range(0.1..1.5),
            };
            let spheres: Vec<(u32, Sphere)> = (0..lanes)
                .map(|i| {
                    let sphere = match i % 3 {
                        0 => first,
                        1 => Sphere {
                            center: coordinate(&mut rng, 2.0),
                            radius: rng.random_range(0.1..1.5),
                        },
                        _ => Sphere {
                            center: Vec3::ZERO,
                            radius: rng.random_range(0.01..0.5),
                        },
                    };
                    (i as u32, sphere)
                })
                .collect();
            let packet = TrianglePacket::spheres(&spheres);
            let origin = if case % 4 == 0 {
                first.center
            } else {
                coordinate(&mut rng, 4.0)
            };
            let target = if case % 2 == 0 {
                Vec3::ZERO
            } else {
                coordinate(&mut rng, 2.0)
            };
            let Some(dir) = (target - origin).try_normalize() else {
                continue;
            };
            let ray = Ray::new(origin, dir);
            let t_max = if case % 5 == 0 {
                rng.random_range(0.1..4.0)
            } else {
                Float::INFINITY
            };
            let lanes_ray = PacketRay::new(&ray);
            let expected = scalar_nearest(&spheres, &ray, t_max);
            let got = packet.intersect_any_kind(&lanes_ray, t_max);
            assert_eq!(
                got.map(|(lane, hit)| (lane, hit.t.to_bits())),
                expected.map(|(lane, hit)| (lane, hit.t.to_bits())),
                "case {case}: {spheres:?} {ray:?}"
            );
            assert_eq!(got, expected);
            assert_eq!(
                packet.occludes_any_kind(&lanes_ray, t_max),
                expected.is_some()
            );
            hits += usize::from(got.is_some());
            inside += usize::from(case % 4 == 0 && got.is_some());
        }
        assert!(
            hits > 5_000 && inside > 1_000,
            "{hits} hits, {inside} from inside"
        );
    }
}
