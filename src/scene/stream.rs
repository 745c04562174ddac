//! Closest hits and blockers of an array of independent rays
//! ([`Scene::intersect_primitives`], [`Scene::occluded_rays`]), the queries a
//! ray-casting library answers for a caller's rays. In a scene larger than the
//! processor's last-level cache, each ray mostly waits for its next node or leaf to
//! come from memory, so the rays are walked several at a time
//! ([`WideBvh::walk_interleaved`](crate::bvh::WideBvh::walk_interleaved),
//! [`walk_interleaved_any`](crate::bvh::WideBvh::walk_interleaved_any)); in a smaller
//! one, ray by ray, which is faster there. Either way they give the answers of
//! [`Scene::intersect_primitive`] and [`Scene::occluded`], bit for bit.

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

/// The slab tests' set-up of up to [`CHUNK`] rays, for one interleaved walk (slots
/// past the rays repeat the first one, and are not walked).
fn queries_of(rays: &[Ray]) -> [RayQuery; CHUNK] {
    std::array::from_fn(|i| RayQuery::new(rays.get(i).unwrap_or(&rays[0])))
}

/// Whether most of `rays` run nearly parallel (within about 8 degrees) to one of the
/// four rays before them: the shadow rays of neighbouring points towards a few
/// lights, or the camera rays of neighbouring pixels. Such rays find the nodes and
/// leaves their neighbours read in the caches, so several in flight would only add
/// bookkeeping. Incoherent rays (bounces, ambient occlusion) are almost never so.
fn coherent(rays: &[Ray]) -> bool {
    let parallel = (0..rays.len())
        .filter(|&i| (1..=4.min(i)).any(|k| rays[i].dir.dot(rays[i - k].dir) > 0.99))
        .count();
    2 * parallel > rays.len()
}

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

    /// [`Scene::occluded`] of every ray of `rays` within its reach `t_max[i]`, into
    /// `blocked`: the same answers. In scenes larger than [`INTERLEAVE_ABOVE_BYTES`],
    /// each run of 64 rays that is not coherent (most of them within about 8 degrees
    /// of one of the four rays before them) is walked several rays at a time (on the
    /// 871k-triangle dragon's bounce directions with no limit: 1.20x ray by ray);
    /// coherent runs, which find their nodes in the caches, are traced ray by ray
    /// (the dragon's shadow rays walked eight at a time: 0.88x). Runs on the calling
    /// thread.
    ///
    /// # Panics
    /// If `t_max` or `blocked` differ from `rays` in length.
    pub fn occluded_rays(&self, rays: &[Ray], t_max: &[Float], blocked: &mut [bool]) {
        assert_eq!(rays.len(), t_max.len(), "one reach per ray");
        assert_eq!(rays.len(), blocked.len(), "one answer per ray");
        if self.interleaves() {
            self.occluded_rays_interleaved(rays, t_max, blocked);
        } else {
            self.occluded_ray_by_ray(rays, t_max, blocked);
        }
    }

    /// [`Scene::occluded_rays`] one ray after another.
    fn occluded_ray_by_ray(&self, rays: &[Ray], t_max: &[Float], blocked: &mut [bool]) {
        for ((ray, &t_max), blocked) in rays.iter().zip(t_max).zip(blocked) {
            *blocked = self.occluded_inlined(ray, t_max);
        }
    }

    /// [`Scene::occluded_rays`] through interleaved walks for the runs of rays that
    /// are not coherent, whatever the scene's size (for scenes without cutouts).
    fn occluded_rays_interleaved(&self, rays: &[Ray], t_max: &[Float], blocked: &mut [bool]) {
        debug_assert!(!self.has_cutouts);
        for ((rays, t_max), blocked) in rays
            .chunks(CHUNK)
            .zip(t_max.chunks(CHUNK))
            .zip(blocked.chunks_mut(CHUNK))
        {
            if coherent(rays) {
                self.occluded_ray_by_ray(rays, t_max, blocked);
                continue;
            }
            let queries = queries_of(rays);
            let mut reach = [0.0; CHUNK];
            reach[..rays.len()].copy_from_slice(t_max);
            blocked.fill(false);
            self.wide.walk_interleaved_any(
                &queries[..rays.len()],
                &mut reach[..rays.len()],
                &self.packets,
                |ray, first, count, t_max| {
                    let lanes = PacketRay::new(&rays[ray]);
                    blocked[ray] = self.blocker_in_leaf(&lanes, first, count, *t_max);
                    blocked[ray]
                },
            );
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
            let queries = queries_of(rays);
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
        let t_max: Vec<Float> = (0..rays.len()).map(|i| i as Float * 0.03).collect();
        let mut blocked = vec![false; rays.len()];
        scene.occluded_rays(&rays, &t_max, &mut blocked);
        let expected: Vec<_> = rays
            .iter()
            .zip(&t_max)
            .map(|(r, &t)| scene.occluded(r, t))
            .collect();
        assert_eq!(blocked, expected);
    }

    /// Interleaved any-hit walks find a ray blocked exactly when its own walk does,
    /// within reaches from zero to unlimited, for whole chunks and ragged arrays.
    #[test]
    fn interleaved_any_hit_walks_find_what_single_rays_find() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(6);
        // Rays found not blocked, and blocked.
        let mut answers = [0; 2];
        for (n, with_spheres, seed) in [(40, false, 11), (24, true, 12), (1, false, 13)] {
            let scene = generated_scene(n, with_spheres, seed);
            for count in [0, 1, 5, CHUNK, 3 * CHUNK + 17] {
                let rays = random_rays(count, seed + count as u64);
                let t_max: Vec<Float> = (0..count)
                    .map(|i| match i % 5 {
                        0 => Float::INFINITY,
                        1 => 0.0,
                        _ => rng.random_range(0.0..3.0),
                    })
                    .collect();
                // Stale answers must be overwritten, both ways.
                let mut blocked: Vec<bool> = (0..count).map(|i| i % 2 == 0).collect();
                scene.occluded_rays_interleaved(&rays, &t_max, &mut blocked);
                let expected: Vec<bool> = rays
                    .iter()
                    .zip(&t_max)
                    .map(|(r, &t)| scene.occluded(r, t))
                    .collect();
                assert_eq!(blocked, expected, "scene {n}, {count} rays");
                for b in expected {
                    answers[usize::from(b)] += 1;
                }
            }
        }
        assert!(
            answers.iter().all(|&a| a > 150),
            "too few of one answer: {answers:?}"
        );
    }

    /// Shadow rays from neighbouring points towards two lights in turn are coherent
    /// and traced ray by ray; random directions are not. Either way the answers are
    /// the rays' own.
    #[test]
    fn coherent_runs_are_told_from_incoherent_ones() {
        let scene = generated_scene(40, true, 21);
        let lights = [Vec3::new(0.3, 3.0, 0.2), Vec3::new(-2.0, 2.0, 1.0)];
        let mut shadow = Vec::new();
        let mut reach = Vec::new();
        for i in 0..3 * CHUNK {
            let origin = Vec3::new(-0.5 + 0.004 * (i / 2) as Float, 0.0, 0.1);
            let to_light = lights[i % 2] - origin;
            shadow.push(Ray::new(origin, to_light));
            reach.push(to_light.length());
        }
        let random = random_rays(3 * CHUNK, 22);
        for (rays, is_coherent) in [(&shadow, true), (&random, false)] {
            for chunk in rays.chunks(CHUNK) {
                assert_eq!(coherent(chunk), is_coherent);
            }
            let t_max: Vec<Float> = if is_coherent {
                reach.clone()
            } else {
                vec![Float::INFINITY; rays.len()]
            };
            let mut blocked = vec![false; rays.len()];
            scene.occluded_rays_interleaved(rays, &t_max, &mut blocked);
            let expected: Vec<bool> = rays
                .iter()
                .zip(&t_max)
                .map(|(r, &t)| scene.occluded(r, t))
                .collect();
            assert_eq!(blocked, expected);
            assert!(expected.iter().any(|&b| b) && expected.iter().any(|&b| !b));
        }
    }
}
