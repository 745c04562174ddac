//! Closest hits and blockers of an array of independent rays
//! ([`Scene::intersect_primitives`], [`Scene::occluded_rays`]), the queries a
//! ray-casting library answers for a caller's rays. The rays go in chunks of 64.
//! Where most of a chunk's rays run nearly parallel to a ray just before them
//! (camera rays of neighbouring pixels, shadow rays of neighbouring points towards a
//! few lights), its rays are sorted into packets of up to sixteen nearly parallel
//! rays and traced as the renderer traces its 4x4 tiles ([`Scene::occluded_packet`],
//! the closest-hit packet walk). Other chunks go down the tree together, 64 rays at
//! a time ([`WideBvh::walk_stream_closest`], [`WideBvh::walk_stream_any`]; in a
//! scene with instances, the top level so and each copy ray by ray), short runs ray
//! by ray. Every way gives the answers of [`Scene::intersect_primitive`]
//! and [`Scene::occluded`], bit for bit.
//!
//! [`WideBvh::walk_stream_closest`]: crate::bvh::WideBvh::walk_stream_closest
//! [`WideBvh::walk_stream_any`]: crate::bvh::WideBvh::walk_stream_any

use super::Scene;
use crate::bvh::{PACKET_SIZE, RayQuery, STREAM_RAYS};
use crate::math::{Float, Ray};
use crate::shapes::{PacketRay, PrimHit};

/// Rays given to one stream walk: one bit each in its masks.
const CHUNK: usize = STREAM_RAYS;

/// The slab tests' set-up of up to [`CHUNK`] rays, for one stream walk (slots past
/// the rays repeat the first one, and are not walked).
fn queries_of(rays: &[Ray]) -> [RayQuery; CHUNK] {
    std::array::from_fn(|i| RayQuery::new(rays.get(i).unwrap_or(&rays[0])))
}

/// Cosine above which two directions count as nearly parallel (about 8 degrees).
const PARALLEL_COSINE: Float = 0.99;

/// Whether most of `rays` run nearly parallel to one of the four rays before them:
/// the shadow rays of neighbouring points towards a few lights, or the camera rays
/// of neighbouring pixels. Such rays meet the same nodes and leaves, so they are
/// traced as packets ([`packets_of`]). Incoherent rays (bounces, ambient occlusion)
/// are almost never so.
fn coherent(rays: &[Ray]) -> bool {
    // Every eighth ray speaks for its neighbours (every ray in short runs), and the
    // vote ends as soon as either side holds more than half of them: on small
    // scenes, where a ray takes 50 ns, asking every ray cost incoherent arrays 3-5%.
    let step = if rays.len() < 16 { 1 } else { 8 };
    let voters = rays.len().saturating_sub(1) / step;
    let half = voters / 2;
    let (mut parallel, mut apart) = (0, 0);
    let mut i = step;
    while i < rays.len() {
        let dir = rays[i].dir;
        if (1..=4.min(i)).any(|k| dir.dot(rays[i - k].dir) > PARALLEL_COSINE) {
            parallel += 1;
            if parallel > half {
                return true;
            }
        } else {
            apart += 1;
            if apart >= voters - half {
                return false;
            }
        }
        i += step;
    }
    false
}

/// Whether the chunks of one array are coherent, decided by [`coherent`] for every
/// [`CHUNKS_PER_VOTE`]-th chunk and kept for the chunks after it: arrays are mostly
/// of one kind, and on small scenes asking every chunk cost incoherent rays 1.5-2.5%.
#[derive(Default)]
struct Vote {
    chunks: usize,
    coherent: bool,
}

/// Chunks that one [`coherent`] vote decides for.
const CHUNKS_PER_VOTE: usize = 4;

impl Vote {
    fn coherent(&mut self, chunk: &[Ray]) -> bool {
        if self.chunks.is_multiple_of(CHUNKS_PER_VOTE) {
            self.coherent = coherent(chunk);
        }
        self.chunks += 1;
        self.coherent
    }
}

/// Runs of this many rays or fewer of a coherent chunk are traced ray by ray: a
/// packet's set-up costs more than it saves them.
const FEW_RAYS: usize = 3;

/// The rays of a coherent chunk (at most [`CHUNK`]) sorted into packets of up to
/// [`PACKET_SIZE`] rays nearly parallel to their packet's first ray, in the order
/// they come: the rays of neighbouring points towards one light together, apart from
/// those towards another. Each packet is a run of `order`, `(first, count)`.
struct Packets {
    order: [u8; CHUNK],
    runs: [(u8, u8); CHUNK],
    run_count: usize,
}

/// [`Packets`] of a coherent chunk: each ray joins the first open packet whose first
/// ray is nearly parallel to it, or opens one. It runs for every chunk of camera or
/// shadow rays, which take about 20 ns each on a small scene, so it keeps to small
/// arrays of indices, starts each search at the first packet not yet full, and
/// skips the sorting where every packet is a run of consecutive rays (the camera
/// array query on the 11k-triangle dragon: 1.06x). Where every run of sixteen rays
/// is one packet, as camera rays tile by tile are, [`in_parallel_runs`] tells so
/// without the search (the same array query: 1.13x more).
fn packets_of(rays: &[Ray]) -> Packets {
    debug_assert!(rays.len() <= CHUNK);
    if in_parallel_runs(rays) {
        Packets::in_runs(rays.len())
    } else {
        packets_searched(rays)
    }
}

/// [`packets_of`] by its search: each ray against the leaders of the open packets.
fn packets_searched(rays: &[Ray]) -> Packets {
    // Each ray's packet; each packet's size and first ray.
    let mut packet_of = [0u8; CHUNK];
    let mut sizes = [0u8; CHUNK];
    let mut leaders = [0u8; CHUNK];
    let mut packet_count = 0;
    let mut first_open = 0;
    // Whether every ray joined the packet opened last: then each packet is a run of
    // consecutive rays (camera rays tile by tile, shadow rays light by light).
    let mut in_runs = true;
    for (i, ray) in rays.iter().enumerate() {
        let joined = (first_open..packet_count).find(|&p| {
            usize::from(sizes[p]) < PACKET_SIZE
                && rays[usize::from(leaders[p])].dir.dot(ray.dir) > PARALLEL_COSINE
        });
        let p = joined.unwrap_or_else(|| {
            leaders[packet_count] = i as u8;
            packet_count += 1;
            packet_count - 1
        });
        in_runs &= p + 1 == packet_count;
        packet_of[i] = p as u8;
        sizes[p] += 1;
        while first_open < packet_count && usize::from(sizes[first_open]) == PACKET_SIZE {
            first_open += 1;
        }
    }
    let mut packets = Packets {
        order: [0; CHUNK],
        runs: [(0, 0); CHUNK],
        run_count: packet_count,
    };
    if in_runs {
        for (i, order) in packets.order.iter_mut().enumerate() {
            *order = i as u8;
        }
        for (run, (&first, &size)) in packets.runs.iter_mut().zip(leaders.iter().zip(&sizes)) {
            *run = (first, size);
        }
        return packets;
    }
    // Where each packet's run starts, then each ray in arrival order into its run.
    let mut at = 0u8;
    for (run, &size) in packets.runs.iter_mut().zip(&sizes[..packet_count]) {
        *run = (at, 0);
        at += size;
    }
    for (i, &p) in packet_of[..rays.len()].iter().enumerate() {
        let (first, count) = &mut packets.runs[usize::from(p)];
        packets.order[usize::from(*first + *count)] = i as u8;
        *count += 1;
    }
    packets
}

/// Whether each run of [`PACKET_SIZE`] rays (from the first) runs nearly parallel to
/// its first ray, as camera rays given tile by tile do. [`packets_of`]'s search then
/// makes exactly these runs its packets, and this test finds so at a fraction of the
/// cost: it has no search and no branch per ray.
fn in_parallel_runs(rays: &[Ray]) -> bool {
    rays.chunks(PACKET_SIZE).all(|run| {
        let lead = run[0].dir;
        run.iter()
            .fold(true, |all, ray| all & (lead.dot(ray.dir) > PARALLEL_COSINE))
    })
}

/// The range of a packet's rays when they are consecutive in the chunk (its indices
/// ascend, as [`packets_of`] lists them).
fn contiguous(members: &[u8]) -> Option<std::ops::Range<usize>> {
    let first = usize::from(*members.first()?);
    let last = usize::from(*members.last()?);
    (last - first + 1 == members.len()).then_some(first..last + 1)
}

impl Packets {
    /// `ray_count` rays in runs of [`PACKET_SIZE`] (the last one shorter), in order.
    fn in_runs(ray_count: usize) -> Packets {
        let mut packets = Packets {
            order: std::array::from_fn(|i| i as u8),
            runs: [(0, 0); CHUNK],
            run_count: ray_count.div_ceil(PACKET_SIZE),
        };
        for (k, run) in packets.runs[..packets.run_count].iter_mut().enumerate() {
            let first = k * PACKET_SIZE;
            *run = (first as u8, (ray_count - first).min(PACKET_SIZE) as u8);
        }
        packets
    }

    /// Each packet's rays, as indices into the chunk.
    fn each(&self) -> impl Iterator<Item = &[u8]> {
        self.runs[..self.run_count]
            .iter()
            .map(|&(first, count)| &self.order[first as usize..(first + count) as usize])
    }
}

impl Scene {
    /// [`Scene::intersect_primitive`] of every ray of `rays`, into `hits` (the
    /// closest primitive, in leaf order, with distance and barycentric coordinates):
    /// the same answers, coherent runs of rays in packets (the dragon's camera rays
    /// given row by row: 1.4x-1.7x ray by ray) and incoherent ones down the tree 64
    /// at a time ([`WideBvh::walk_stream_closest`]; the dragon's bounce rays:
    /// 1.14x-1.23x ray by ray on its 11k to 203k-triangle meshes, 1.1x on the 871k
    /// one, where eight rays in flight at once did as well). Runs on the calling
    /// thread; callers split large arrays between threads.
    ///
    /// [`WideBvh::walk_stream_closest`]: crate::bvh::WideBvh::walk_stream_closest
    ///
    /// # Panics
    /// If `hits` and `rays` differ in length.
    pub fn intersect_primitives(&self, rays: &[Ray], hits: &mut [Option<(u32, PrimHit)>]) {
        assert_eq!(rays.len(), hits.len(), "one hit per ray");
        if self.ray_by_ray || (self.wide.nodes.is_empty() && self.instances.is_none()) {
            self.intersect_primitives_ray_by_ray(rays, hits);
            return;
        }
        let mut vote = Vote::default();
        for (rays, hits) in rays.chunks(CHUNK).zip(hits.chunks_mut(CHUNK)) {
            if vote.coherent(rays) {
                self.intersect_primitives_in_packets(rays, hits);
            } else if rays.len() <= FEW_RAYS {
                self.intersect_primitives_ray_by_ray(rays, hits);
            } else if let Some(instances) = &self.instances {
                // The top level as a stream, each copy ray by ray (incoherent rays
                // through the top level as packets of sixteen, each copy too,
                // measured 0.77x ray by ray on the 10,000-dragon field).
                self.intersect_primitives_instanced_streamed(instances, rays, hits);
            } else {
                self.intersect_primitives_streamed(rays, hits);
            }
        }
    }

    /// [`Scene::intersect_primitives`] one ray after another.
    fn intersect_primitives_ray_by_ray(&self, rays: &[Ray], hits: &mut [Option<(u32, PrimHit)>]) {
        for (ray, hit) in rays.iter().zip(hits) {
            *hit = self.intersect_primitive(ray);
        }
    }

    /// [`Scene::intersect_primitives`] of a coherent chunk, packet by packet
    /// ([`packets_of`]; for scenes without cutouts).
    fn intersect_primitives_in_packets(&self, rays: &[Ray], hits: &mut [Option<(u32, PrimHit)>]) {
        for members in packets_of(rays).each() {
            if members.len() <= FEW_RAYS {
                for &i in members {
                    hits[i as usize] = self.intersect_primitive(&rays[i as usize]);
                }
                continue;
            }
            if let Some(run) = contiguous(members) {
                // Rays given in packet order (tiles of camera rays): no copy.
                let found = self.named_packet(&rays[run.clone()]);
                for (hit, found) in hits[run].iter_mut().zip(found) {
                    *hit = found;
                }
                continue;
            }
            let packet: [Ray; PACKET_SIZE] =
                std::array::from_fn(|k| rays[members[k.min(members.len() - 1)] as usize]);
            let found = self.named_packet(&packet[..members.len()]);
            for (&i, found) in members.iter().zip(found) {
                hits[i as usize] = found;
            }
        }
    }

    /// [`Scene::occluded`] of every ray of `rays` within its reach `t_max[i]`, into
    /// `blocked`: the same answers. Coherent runs of 64 rays (most of them within
    /// about 8 degrees of one of the four rays before them) are traced in packets of
    /// nearly parallel rays (the dragon's shadow rays towards two lights in turn:
    /// 1.3x ray by ray on the 871k-triangle dragon, 1.7x on the 11k one). The other
    /// runs go down the tree 64 rays at a time ([`WideBvh::walk_stream_any`]; the
    /// dragon's bounce directions with no limit: 1.23x-1.30x ray by ray on the 11k to
    /// 203k-triangle meshes, 1.2x on the 871k one, as fast there as walking eight
    /// rays at a time). Runs on the calling thread.
    ///
    /// [`WideBvh::walk_stream_any`]: crate::bvh::WideBvh::walk_stream_any
    ///
    /// # Panics
    /// If `t_max` or `blocked` differ from `rays` in length.
    pub fn occluded_rays(&self, rays: &[Ray], t_max: &[Float], blocked: &mut [bool]) {
        assert_eq!(rays.len(), t_max.len(), "one reach per ray");
        assert_eq!(rays.len(), blocked.len(), "one answer per ray");
        if self.ray_by_ray || (self.wide.nodes.is_empty() && self.instances.is_none()) {
            self.occluded_ray_by_ray(rays, t_max, blocked);
            return;
        }
        let mut vote = Vote::default();
        for ((rays, t_max), blocked) in rays
            .chunks(CHUNK)
            .zip(t_max.chunks(CHUNK))
            .zip(blocked.chunks_mut(CHUNK))
        {
            if vote.coherent(rays) {
                self.occluded_in_packets(rays, t_max, blocked);
            } else if rays.len() <= FEW_RAYS {
                self.occluded_ray_by_ray(rays, t_max, blocked);
            } else if let Some(instances) = &self.instances {
                self.occluded_instanced_streamed(instances, rays, t_max, blocked);
            } else {
                self.occluded_streamed(rays, t_max, blocked);
            }
        }
    }

    /// [`Scene::occluded_rays`] of a coherent chunk, packet by packet
    /// ([`packets_of`]; for scenes without cutouts).
    fn occluded_in_packets(&self, rays: &[Ray], t_max: &[Float], blocked: &mut [bool]) {
        for members in packets_of(rays).each() {
            if members.len() <= FEW_RAYS {
                for &i in members {
                    let i = i as usize;
                    blocked[i] = self.occluded_inlined(&rays[i], t_max[i]);
                }
                continue;
            }
            let n = members.len();
            if let Some(run) = contiguous(members) {
                let mask =
                    self.occluded_packet(&rays[run.clone()], &t_max[run.clone()], (1 << n) - 1);
                for (k, blocked) in blocked[run].iter_mut().enumerate() {
                    *blocked = mask >> k & 1 != 0;
                }
                continue;
            }
            let packet: [Ray; PACKET_SIZE] =
                std::array::from_fn(|k| rays[members[k.min(members.len() - 1)] as usize]);
            let reach: [Float; PACKET_SIZE] =
                std::array::from_fn(|k| t_max[members[k.min(members.len() - 1)] as usize]);
            let mask = self.occluded_packet(&packet[..n], &reach[..n], (1u32 << n) - 1);
            for (k, &i) in members.iter().enumerate() {
                blocked[i as usize] = mask >> k & 1 != 0;
            }
        }
    }

    /// [`Scene::occluded_rays`] one ray after another.
    fn occluded_ray_by_ray(&self, rays: &[Ray], t_max: &[Float], blocked: &mut [bool]) {
        for ((ray, &t_max), blocked) in rays.iter().zip(t_max).zip(blocked) {
            *blocked = self.occluded_inlined(ray, t_max);
        }
    }

    /// [`Scene::occluded_rays`] of a chunk (at most [`STREAM_RAYS`]) through one
    /// stream walk (for scenes without cutouts).
    fn occluded_streamed(&self, rays: &[Ray], t_max: &[Float], blocked: &mut [bool]) {
        debug_assert!(!self.has_cutouts && rays.len() <= CHUNK);
        let queries = queries_of(rays);
        let answers = self.wide.walk_stream_any(
            &queries[..rays.len()],
            t_max,
            &self.packets,
            |ray, first, count, t_max| {
                let lanes = PacketRay::new(&rays[ray]);
                self.blocker_in_leaf(&lanes, first, count, t_max)
            },
        );
        for (i, blocked) in blocked.iter_mut().enumerate() {
            *blocked = answers >> i & 1 != 0;
        }
    }

    /// [`Scene::intersect_primitives`] of a chunk (at most [`STREAM_RAYS`]) through
    /// one stream walk (for scenes without cutouts). The rays whose answer could
    /// depend on the order of their leaves are traced again on their own.
    fn intersect_primitives_streamed(&self, rays: &[Ray], hits: &mut [Option<(u32, PrimHit)>]) {
        debug_assert!(!self.has_cutouts && rays.len() <= CHUNK);
        let queries = queries_of(rays);
        let mut t_max = [Float::INFINITY; CHUNK];
        let mut closest = [None; CHUNK];
        let mut order_matters = 0u64;
        self.wide.walk_stream_closest(
            &queries[..rays.len()],
            &mut t_max[..rays.len()],
            &self.packets,
            |ray, first, count, entry, t_max| {
                let lanes = PacketRay::new(&rays[ray]);
                if self.nearest_in_leaf_noting_order(
                    &lanes,
                    first,
                    count,
                    entry,
                    t_max,
                    &mut closest[ray],
                ) {
                    order_matters |= 1 << ray;
                }
            },
        );
        while order_matters != 0 {
            let ray = order_matters.trailing_zeros() as usize;
            order_matters &= order_matters - 1;
            closest[ray] = self.closest_lane(&rays[ray]);
        }
        for (hit, found) in hits.iter_mut().zip(closest) {
            *hit = self.named(found);
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

    /// Closest-hit streams give every ray the primitive, distance and barycentrics
    /// of its own walk, bit for bit, for arrays that fill whole chunks and for ragged
    /// ones (one ray, none).
    #[test]
    fn closest_hit_streams_find_what_single_rays_find() {
        for (n, with_spheres, seed) in [(40, false, 1), (24, true, 2), (1, false, 3)] {
            let scene = generated_scene(n, with_spheres, seed);
            assert!(!scene.has_cutouts);
            for count in [0, 1, 5, CHUNK, 3 * CHUNK + 17] {
                let rays = random_rays(count, seed + count as u64);
                assert!(
                    count < CHUNK || assert_streamed_hits(&scene, &rays) > count / 4,
                    "too few hits to mean anything"
                );
            }
        }
    }

    /// Where a ray's answer depends on the order of its leaves (rays straight down
    /// onto eight overlapping flat grids in one plane, shifted by quarters of a cell
    /// and cut along either diagonal: hits at exactly the same distance in several
    /// leaves, in the plane of the leaves' boxes), the stream still gives each ray
    /// its own walk's answer.
    #[test]
    fn closest_hit_streams_keep_single_rays_answers_where_order_matters() {
        let mut d = crate::description::SceneDescription::default();
        let n = 12u32;
        for grid in 0..8u32 {
            let shift = Vec3::new((grid % 4) as Float * 0.25, 0.0, (grid / 4) as Float * 0.5);
            let first = d.positions.len() as u32;
            for j in 0..=n {
                for i in 0..=n {
                    d.positions
                        .push(shift + Vec3::new(i as Float, 0.0, j as Float));
                }
            }
            let at = |i: u32, j: u32| first + j * (n + 1) + i;
            for j in 0..n {
                for i in 0..n {
                    let [a, b, c, e] = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)];
                    let halves = if grid % 2 == 0 {
                        [[a, c, b], [a, e, c]]
                    } else {
                        [[a, e, b], [b, e, c]]
                    };
                    for positions in halves {
                        d.triangles.push(crate::description::TriangleDesc {
                            positions,
                            material: crate::material::MaterialId(0),
                        });
                    }
                }
            }
        }
        d.materials = vec![crate::material::Material::named("grey")];
        let scene = Scene::build(d, &crate::bvh::BvhParams::default());
        // Through vertices, edges and faces, from several heights.
        let rays: Vec<Ray> = (0..8 * CHUNK)
            .map(|k| {
                let (x, z) = ((k % 53) as Float * 0.25, (k * 7 % 53) as Float * 0.25);
                Ray::new(Vec3::new(x, 1.0 + (k % 3) as Float, z), -Vec3::Y)
            })
            .collect();
        assert!(assert_streamed_hits(&scene, &rays) > rays.len() * 9 / 10);
    }

    /// Checks [`Scene::intersect_primitives_streamed`] of `rays`, chunk by chunk,
    /// against [`Scene::intersect_primitive`] bit for bit; returns how many hit.
    fn assert_streamed_hits(scene: &Scene, rays: &[Ray]) -> usize {
        let mut hits = vec![None; rays.len()];
        for (rays, hits) in rays.chunks(CHUNK).zip(hits.chunks_mut(CHUNK)) {
            scene.intersect_primitives_streamed(rays, hits);
        }
        let bits = |h: &Option<(u32, PrimHit)>| {
            h.map(|(prim, h)| (prim, h.t.to_bits(), h.u.to_bits(), h.v.to_bits()))
        };
        for (i, (ray, hit)) in rays.iter().zip(&hits).enumerate() {
            assert_eq!(bits(hit), bits(&scene.intersect_primitive(ray)), "ray {i}");
        }
        hits.iter().filter(|h| h.is_some()).count()
    }

    /// Both array queries of `rays` give each ray its own answer: the blocker within
    /// `t_max`, and the closest primitive, distance and barycentrics, bit for bit.
    /// Returns how many rays are blocked and how many hit something.
    fn assert_array_answers(scene: &Scene, rays: &[Ray], t_max: &[Float]) -> (usize, usize) {
        let mut blocked = vec![false; rays.len()];
        scene.occluded_rays(rays, t_max, &mut blocked);
        let expected: Vec<bool> = rays
            .iter()
            .zip(t_max)
            .map(|(r, &t)| scene.occluded(r, t))
            .collect();
        assert_eq!(blocked, expected);
        let mut hits = vec![None; rays.len()];
        scene.intersect_primitives(rays, &mut hits);
        let bits = |h: &Option<(u32, PrimHit)>| {
            h.map(|(prim, h)| (prim, h.t.to_bits(), h.u.to_bits(), h.v.to_bits()))
        };
        for (ray, hit) in rays.iter().zip(&hits) {
            assert_eq!(bits(hit), bits(&scene.intersect_primitive(ray)));
        }
        let blocked = blocked.iter().filter(|&&b| b).count();
        (blocked, hits.iter().filter(|h| h.is_some()).count())
    }

    /// Stream walks find a ray blocked exactly when its own walk does, within
    /// reaches from zero to unlimited, for whole chunks and ragged arrays.
    #[test]
    fn stream_walks_find_what_single_rays_find() {
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
                for ((rays, t_max), blocked) in rays
                    .chunks(CHUNK)
                    .zip(t_max.chunks(CHUNK))
                    .zip(blocked.chunks_mut(CHUNK))
                {
                    scene.occluded_streamed(rays, t_max, blocked);
                }
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

    /// Shadow rays from points along a line towards two lights in turn, with their
    /// distances to the lights.
    fn shadow_rays(count: usize) -> (Vec<Ray>, Vec<Float>) {
        let lights = [Vec3::new(0.3, 3.0, 0.2), Vec3::new(-2.0, 2.0, 1.0)];
        (0..count)
            .map(|i| {
                let origin = Vec3::new(-0.5 + 0.004 * (i / 2) as Float, 0.0, 0.1);
                let to_light = lights[i % 2] - origin;
                (Ray::new(origin, to_light), to_light.length())
            })
            .unzip()
    }

    /// Camera rays through a grid of pixels, row by row, from above the generated
    /// scene.
    fn camera_rays(width: usize, height: usize) -> Vec<Ray> {
        let eye = Vec3::new(0.1, 1.5, 1.8);
        (0..width * height)
            .map(|i| {
                let (x, y) = ((i % width) as Float, (i / width) as Float);
                let target = Vec3::new(
                    -0.9 + 1.8 * x / width as Float,
                    0.0,
                    -0.9 + 1.8 * y / height as Float,
                );
                Ray::new(eye, target - eye)
            })
            .collect()
    }

    /// Shadow rays from neighbouring points towards two lights in turn, and camera
    /// rays, are coherent; random directions are not. Either way the answers are the
    /// rays' own, bit for bit, whether the scene interleaves or not.
    #[test]
    fn coherent_runs_are_told_from_incoherent_ones() {
        let scene = generated_scene(40, true, 21);
        let (shadow, reach) = shadow_rays(3 * CHUNK + 9);
        let random = random_rays(3 * CHUNK, 22);
        let camera = camera_rays(24, 16);
        for chunk in shadow.chunks(CHUNK).chain(camera.chunks(CHUNK)) {
            assert!(coherent(chunk));
        }
        for chunk in random.chunks(CHUNK) {
            assert!(!coherent(chunk));
        }
        for (rays, t_max) in [
            (&shadow, reach.clone()),
            (&random, vec![Float::INFINITY; random.len()]),
            (&camera, vec![Float::INFINITY; camera.len()]),
        ] {
            let (blocked, hits) = assert_array_answers(&scene, rays, &t_max);
            assert!(blocked > 0 && blocked < rays.len());
            assert!(hits > rays.len() / 4);
        }
    }

    /// One vote decides for four chunks: an array that turns incoherent after its
    /// first chunk is traced as coherent up to the next vote, with the rays' own
    /// answers either way.
    #[test]
    fn one_vote_decides_for_four_chunks() {
        let (shadow, reach) = shadow_rays(CHUNK);
        let random = random_rays(5 * CHUNK, 25);
        let rays: Vec<Ray> = shadow.iter().chain(&random).copied().collect();
        let mut vote = Vote::default();
        let decided: Vec<bool> = rays.chunks(CHUNK).map(|c| vote.coherent(c)).collect();
        assert_eq!(decided, [true, true, true, true, false, false]);
        let scene = generated_scene(40, false, 26);
        let t_max: Vec<Float> = reach
            .iter()
            .copied()
            .chain(std::iter::repeat_n(Float::INFINITY, random.len()))
            .collect();
        assert_array_answers(&scene, &rays, &t_max);
    }

    /// A coherent chunk's rays go into packets of nearly parallel rays, each ray in
    /// exactly one: the shadow rays towards two lights in turn into packets of one
    /// light each, full ones first.
    #[test]
    fn coherent_chunks_split_into_packets_of_parallel_rays() {
        let (shadow, _) = shadow_rays(CHUNK);
        let packets = packets_of(&shadow);
        let mut seen = [false; CHUNK];
        let mut sizes = Vec::new();
        for members in packets.each() {
            assert!(!members.is_empty() && members.len() <= PACKET_SIZE);
            let lead = shadow[members[0] as usize].dir;
            for &i in members {
                assert!(
                    !std::mem::replace(&mut seen[i as usize], true),
                    "ray {i} twice"
                );
                assert!(shadow[i as usize].dir.dot(lead) > PARALLEL_COSINE);
                assert_eq!(i % 2, members[0] % 2, "one light per packet");
            }
            sizes.push(members.len());
        }
        assert!(seen.iter().all(|&s| s));
        assert_eq!(sizes, [16, 16, 16, 16]);
        // Rays in every direction: mostly packets of one.
        let random = random_rays(CHUNK, 23);
        assert!(packets_of(&random).each().count() > CHUNK / 2);
    }

    /// Camera rays given tile by tile are runs of sixteen nearly parallel rays: the
    /// test without a search finds so, and its packets are the search's, for full and
    /// ragged chunks. Shadow rays towards two lights in turn are not such runs.
    #[test]
    fn runs_of_parallel_rays_are_packets_without_a_search() {
        let camera = camera_rays(128, 8);
        for count in [1, 17, 40, CHUNK] {
            let rays = &camera[..count];
            assert!(in_parallel_runs(rays), "{count} rays");
            let (quick, searched) = (Packets::in_runs(count), packets_searched(rays));
            assert!(quick.each().eq(searched.each()), "{count} rays");
        }
        let (shadow, _) = shadow_rays(CHUNK);
        assert!(!in_parallel_runs(&shadow));
        assert!(!in_parallel_runs(&random_rays(CHUNK, 27)));
    }

    /// A chunk traced in packets gives each ray its own answer, for packets of every
    /// size up to full and rays traced one by one among them.
    #[test]
    fn packets_of_a_chunk_find_what_single_rays_find() {
        let scene = generated_scene(40, false, 24);
        let (shadow, reach) = shadow_rays(CHUNK);
        for count in [1, FEW_RAYS, FEW_RAYS + 1, 17, 40, CHUNK] {
            let (rays, t_max) = (&shadow[..count], &reach[..count]);
            let mut blocked = vec![true; count];
            scene.occluded_in_packets(rays, t_max, &mut blocked);
            let expected: Vec<bool> = rays
                .iter()
                .zip(t_max)
                .map(|(r, &t)| scene.occluded(r, t))
                .collect();
            assert_eq!(blocked, expected, "{count} rays");
            let mut hits = vec![None; count];
            scene.intersect_primitives_in_packets(rays, &mut hits);
            let expected: Vec<_> = rays.iter().map(|r| scene.intersect_primitive(r)).collect();
            assert_eq!(hits, expected, "{count} rays");
        }
    }
}
