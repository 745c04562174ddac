//! Closest hits of an array of independent rays ([`Scene::intersect_primitives`]),
//! the query a ray-casting library answers for a caller's rays. In a scene larger
//! than the processor's last-level cache, each ray mostly waits for its next node or
//! leaf to come from memory, so the rays are walked several at a time
//! ([`WideBvh::walk_interleaved`](crate::bvh::WideBvh::walk_interleaved)); in a
//! smaller one, ray by ray, which is faster there. Both give the answers of
//! [`Scene::intersect_primitive`], bit for bit.

use super::Scene;
use crate::bvh::RayQuery;
use crate::math::{Float, Ray};
use crate::shapes::{PacketRay, PrimHit};

/// Scenes whose wide BVH nodes and triangle packets take more bytes than this trace
/// arrays of rays several at a time: the size of a last-level cache shared by a few
/// cores on current desktop and server processors (32 MiB on this project's
/// benchmark machine). Measured on the dragon's incoherent bounce rays: 1.10x at
/// 871k triangles (50 MB), 0.90x-0.97x at 203k (12 MB) and 0.78x-0.88x below.
pub const INTERLEAVE_ABOVE_BYTES: usize = 32 << 20;

/// Rays given to one interleaved walk: enough for the walk's rays in flight to be
/// replaced many times, few enough for their state to stay in the first-level cache.
const CHUNK: usize = 64;

impl Scene {
    /// [`Scene::intersect_primitive`] of every ray of `rays`, into `hits` (the
    /// closest primitive, in leaf order, with distance and barycentric coordinates):
    /// the same answers, several rays in flight at once in scenes larger than
    /// [`INTERLEAVE_ABOVE_BYTES`]. Runs on the calling thread; callers split large
    /// arrays between threads.
    ///
    /// # Panics
    /// If `hits` and `rays` differ in length.
    pub fn intersect_primitives(&self, rays: &[Ray], hits: &mut [Option<(u32, PrimHit)>]) {
        assert_eq!(rays.len(), hits.len(), "one hit per ray");
        if self.interleaves() {
            self.intersect_primitives_interleaved(rays, hits);
        } else {
            for (ray, hit) in rays.iter().zip(hits) {
                *hit = self.intersect_primitive(ray);
            }
        }
    }

    /// Bytes of the wide BVH's nodes and the triangle packets: what rays read.
    pub fn acceleration_bytes(&self) -> usize {
        size_of_val(&self.wide.nodes[..]) + size_of_val(&self.packets[..])
    }

    /// Whether [`Scene::intersect_primitives`] walks several rays at a time.
    fn interleaves(&self) -> bool {
        // Cutouts need a shading lookup per hit, which the interleaved leaf test
        // does not make.
        !self.has_cutouts && self.acceleration_bytes() > INTERLEAVE_ABOVE_BYTES
    }

    /// [`Scene::intersect_primitives`] through interleaved walks, whatever the
    /// scene's size (for scenes without cutouts).
    fn intersect_primitives_interleaved(&self, rays: &[Ray], hits: &mut [Option<(u32, PrimHit)>]) {
        debug_assert!(!self.has_cutouts);
        for (rays, hits) in rays.chunks(CHUNK).zip(hits.chunks_mut(CHUNK)) {
            let queries: [RayQuery; CHUNK] =
                std::array::from_fn(|i| RayQuery::new(rays.get(i).unwrap_or(&rays[0])));
            let mut t_max = [Float::INFINITY; CHUNK];
            let mut closest = [None; CHUNK];
            self.wide.walk_interleaved(
                &queries[..rays.len()],
                &mut t_max[..rays.len()],
                &self.packets,
                |ray, first, count, t_max| {
                    let lanes = PacketRay::new(&rays[ray]);
                    self.nearest_in_leaf(&lanes, first, count, t_max, &mut closest[ray]);
                    false
                },
            );
            for (hit, found) in hits.iter_mut().zip(closest) {
                *hit = found.and_then(|(packet, lane, hit)| {
                    Some((self.packets[packet as usize].prim(lane)?, hit))
                });
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::packet_tests::generated_scene;
    use super::*;
    use crate::math::Vec3;
    use rand::{Rng, SeedableRng};

    /// Rays from above the generated scene's height field, from points on its
    /// surface (as bounces leave it) and from far outside, in every direction, some
    /// along an axis: many hits, misses and rays that cross shared edges.
    fn random_rays(count: usize, seed: u64) -> Vec<Ray> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        (0..count)
            .map(|i| {
                let origin = match i % 3 {
                    0 => Vec3::new(
                        rng.random_range(-1.0..1.0),
                        rng.random_range(0.0..2.0),
                        rng.random_range(-1.0..1.0),
                    ),
                    1 => Vec3::new(
                        rng.random_range(-1.0..1.0),
                        0.0,
                        rng.random_range(-1.0..1.0),
                    ),
                    _ => Vec3::new(0.0, 0.5, 5.0),
                };
                let dir = match i % 7 {
                    0 => -Vec3::Y,
                    _ => Vec3::new(
                        rng.random_range(-1.0..1.0),
                        rng.random_range(-1.0..1.0),
                        rng.random_range(-1.0..1.0),
                    ),
                };
                let dir = if dir.length() < 1e-3 { Vec3::X } else { dir };
                Ray::new(origin, dir.normalize())
            })
            .collect()
    }

    /// Interleaved walks give every ray the primitive, distance and barycentrics of
    /// its own walk, bit for bit, for arrays that fill whole chunks and for ragged
    /// ones (fewer rays than a walk keeps in flight, one ray, none).
    #[test]
    fn interleaved_walks_find_what_single_rays_find() {
        for (n, with_spheres, seed) in [(40, false, 1), (24, true, 2), (1, false, 3)] {
            let scene = generated_scene(n, with_spheres, seed);
            assert!(!scene.has_cutouts);
            for count in [0, 1, 5, CHUNK, 3 * CHUNK + 17] {
                let rays = random_rays(count, seed + count as u64);
                let mut hits = vec![None; count];
                scene.intersect_primitives_interleaved(&rays, &mut hits);
                let expected: Vec<_> = rays.iter().map(|r| scene.intersect_primitive(r)).collect();
                assert!(
                    count < CHUNK || expected.iter().filter(|h| h.is_some()).count() > count / 4,
                    "too few hits to mean anything"
                );
                for (i, (hit, expected)) in hits.iter().zip(&expected).enumerate() {
                    let bits = |h: &Option<(u32, PrimHit)>| {
                        h.map(|(prim, h)| (prim, h.t.to_bits(), h.u.to_bits(), h.v.to_bits()))
                    };
                    assert_eq!(bits(hit), bits(expected), "scene {n}, ray {i} of {count}");
                }
            }
        }
    }

    /// Small scenes are traced ray by ray, and only scenes larger than the threshold
    /// are interleaved.
    #[test]
    fn only_scenes_larger_than_the_cache_are_interleaved() {
        let scene = generated_scene(40, true, 4);
        let bytes = scene.acceleration_bytes();
        let packets = scene.bvh_summary().packets;
        assert!(
            bytes >= packets * 160 && bytes < INTERLEAVE_ABOVE_BYTES,
            "{bytes}"
        );
        assert!(!scene.interleaves());
        let rays = random_rays(100, 5);
        let mut hits = vec![None; rays.len()];
        scene.intersect_primitives(&rays, &mut hits);
        let expected: Vec<_> = rays.iter().map(|r| scene.intersect_primitive(r)).collect();
        assert_eq!(hits, expected);
    }
}
