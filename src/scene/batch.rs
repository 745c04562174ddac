//! Closest-hit and any-hit queries for a batch of up to [`BATCH`] independent rays at
//! once, for path mode: the paths of one pixel advance together (a wavefront), and
//! their rays, however incoherent, are traced together, SIMD across the rays as
//! Mitsuba's and Embree's ray streams are.
//!
//! The batch walks the wide BVH as one: a node is fetched once, each child box is
//! tested against all the batch's rays in one 16-lane pass, and a child goes on the
//! stack when any ray meets it before that ray's closest hit so far; a leaf's
//! primitives are each tested against every ray of the batch in one pass (the
//! primitive broadcast, the rays in the lanes). In a tree of more than
//! [`ORDER_FROM_NODES`] nodes a closest-hit batch visits a node's children nearest
//! first (by the least entry distance of the rays that meet each) and passes over a
//! box whose rays all have a nearer hit already, as a single ray's ordered walk does. Where few rays are left at a node ([`FEW_RAYS`], as
//! happens deep in large scenes with scattered rays), each of them walks that
//! node's subtree by itself, from its closest hit so far, and stays in the batch
//! for the rest: a batch never costs much more than its rays traced alone.
//!
//! A node's boxes meet the batch's rays one box at a time, with no first test of
//! bounds of the whole batch against all eight (full mode's packet walk has one,
//! `bvh::packet`'s frustum). Tried here, built of the unfinished rays, those bounds
//! spared half the sixteen-ray box tests on the rough gold dragon (12M of 26M) yet
//! measured 0.99x-1.0x the CPU time (same-run pairs, 320x240 at 64 samples and
//! 1280x960 at 4): a pixel's rays part after about four nodes there (3.3M batched
//! node visits for 14.4M rays), each node's box tests are a small part of the walk,
//! and the rest of the way is walked ray by ray.
//!
//! A ray's hit is the closest along it; which of two primitives at exactly the same
//! distance wins may depend on the order in which the batch met them, and so on the
//! batch's other rays. Batches are made of the samples of one pixel, the same in
//! every run, on any number of threads and in any tile, so images stay deterministic.
//! Scenes with cutouts or instances are traced ray by ray: through the top level,
//! the packet walk ([`Scene::closest_found_packet`]) cost path mode's batches on
//! the 10,000-dragon field 1.42x the CPU time of single rays (4 samples a pixel,
//! depth 4), its set-up per copy paid for by too few coherent rays.

use std::mem::MaybeUninit;

use wide::f32x16;

use super::{Hit, Scene};
use crate::bvh::{
    PACKET_SIZE, RayPacket, RayQuery, STACK_SIZE, WideNode, lane_mask, lanes_of, reduce_min,
};
use crate::math::{Float, Ray};
use crate::shapes::{LANES, PacketRay, PrimHit, Shape, sphere_across_rays, triangle_across_rays};

/// Rays per batch: one AVX-512 register of `f32` per coordinate.
pub const BATCH: usize = PACKET_SIZE;

/// At a node met by this many rays or fewer, each of those rays walks the node's
/// subtree by itself: a batch tests a node's eight boxes one by one, each for
/// sixteen lanes, where a ray alone tests all eight in one pass, so the batch pays
/// only for several rays. Measured on the rough gold dragon (path mode, 64 spp,
/// same-run pairs): 4 cost 0.87x the CPU time of 1, 6 and 8 about 0.95x, 16 (no
/// batch walk at all) 1.01x; leaves stay batched (a few rays tested one by one
/// there cost 0.96x-1.0x, no gain).
const FEW_RAYS: u32 = 4;

/// A closest-hit batch orders a node's children nearest first only in trees of more
/// than this many 8-wide nodes: in a small scene (the Cornell box is one node over
/// five leaves) there is little behind a near hit to skip, and finding each child's
/// least entry distance and sorting cost the path-mode Cornell box 1.06x the CPU
/// time of the unordered walk (same-run pairs), while the rough gold dragon (tens of
/// thousands of nodes) gains from the order.
const ORDER_FROM_NODES: usize = 16;

/// All-ones in the lanes of the rays of `batch` that hit `shape` with `0 < t <
/// t_max`, and their `t`, `u`, `v` (zero for spheres): lane by lane the single-ray
/// kernels' operations.
#[inline(always)]
fn shape_across(
    batch: &RayPacket,
    shape: &Shape,
    t_max: f32x16,
) -> (f32x16, f32x16, f32x16, f32x16) {
    let (valid, t, u, v) = match shape {
        Shape::Triangle(triangle) => triangle_across_rays(triangle, &batch.origin, &batch.dir),
        Shape::Sphere(sphere) => {
            let (valid, t) = sphere_across_rays(sphere, &batch.origin, &batch.dir);
            (valid, t, f32x16::ZERO, f32x16::ZERO)
        }
    };
    (valid & t.simd_lt(t_max), t, u, v)
}

/// Pushes onto `stack` each child of `node` that some ray of `rays` in `batch` meets
/// with an entry distance below its `t_max`, with the mask of those rays and the
/// least of their entry distances; if `ORDERED`, nearest last (on top), by that
/// distance, so that a closest-hit walk finds near hits first and skips what lies
/// behind them, as a single ray's ordered walk does.
#[inline(always)]
fn push_met_children<const ORDERED: bool>(
    batch: &RayPacket,
    node: &WideNode,
    t_max: f32x16,
    rays: u32,
    stack: &mut [MaybeUninit<Pending>],
    stack_len: &mut usize,
) {
    // Slots in use: an unused slot's box is inverted.
    let used = node.planes[0].simd_le(node.planes[1]).to_bitmask();
    let run_start = *stack_len;
    let open = lane_mask(rays);
    for slot in lanes_of(used) {
        let planes = [0, 1, 2, 3, 4, 5].map(|p| node.planes[p].as_array()[slot]);
        let (met, t_enter) = batch.hit_child::<false>(&planes, t_max);
        let met_mask = met & open;
        let met = met_mask.to_bitmask() & rays;
        if met != 0 {
            debug_assert!(*stack_len < STACK_SIZE);
            let t_enter = if ORDERED {
                reduce_min(met_mask.select(t_enter, f32x16::splat(Float::INFINITY)))
            } else {
                0.0
            };
            stack[*stack_len].write(Pending {
                index: node.child(slot),
                item_count: node.item_count[slot],
                rays: met,
                t_enter,
            });
            *stack_len += 1;
        }
    }
    if ORDERED {
        // Insertion sort by decreasing entry distance: at most eight entries.
        for i in run_start + 1..*stack_len {
            // SAFETY: entries `run_start..stack_len` were written just above.
            let entry = unsafe { stack[i].assume_init() };
            let mut j = i;
            while j > run_start && unsafe { stack[j - 1].assume_init() }.t_enter < entry.t_enter {
                stack[j] = stack[j - 1];
                j -= 1;
            }
            stack[j].write(entry);
        }
    }
}

/// What the stack of a batch walk holds: a node or a leaf's packets, and the rays
/// that met its box.
#[derive(Clone, Copy)]
struct Pending {
    index: u32,
    item_count: u32,
    rays: u32,
    /// The least entry distance of `rays` into its box (0 in any-hit walks): a ray
    /// whose closest hit so far is no farther has nothing more to find there.
    t_enter: Float,
}

impl Scene {
    /// The closest hit of each ray `rays[i]` whose bit `i` is set in `active`, into
    /// `hits[i]`; other entries of `hits` are left as they are.
    pub fn intersect_batch(
        &self,
        rays: &[Ray; BATCH],
        active: u32,
        hits: &mut [Option<Hit>; BATCH],
    ) {
        if self.ray_by_ray
            || self.instances.is_some()
            || active.count_ones() <= FEW_RAYS
            || self.wide.nodes.is_empty()
        {
            for lane in lanes_of(active) {
                hits[lane] = self.intersect(&rays[lane]);
            }
            return;
        }
        let batch = RayPacket::new(rays);
        let mut t_best = f32x16::splat(Float::INFINITY);
        let mut u_best = f32x16::ZERO;
        let mut v_best = f32x16::ZERO;
        // Packet index times LANES plus lane, as bits in a float lane.
        let mut id_best = f32x16::splat(Float::from_bits(u32::MAX));
        let open = lane_mask(active);
        let mut stack = [const { MaybeUninit::<Pending>::uninit() }; STACK_SIZE];
        stack[0].write(Pending {
            index: 0,
            item_count: 0,
            rays: active,
            t_enter: 0.0,
        });
        let mut stack_len = 1;
        let ordered = self.wide.nodes.len() > ORDER_FROM_NODES;
        while stack_len > 0 {
            stack_len -= 1;
            // SAFETY: entries below `stack_len` were written before.
            let pending = unsafe { stack[stack_len].assume_init() };
            // Rays whose closest hit so far lies before every entry into this box.
            let done = t_best.simd_le(f32x16::splat(pending.t_enter)).to_bitmask();
            let reached = pending.rays & !done;
            if reached == 0 {
                continue;
            }
            if pending.item_count > 0 {
                let first = pending.index as usize;
                let packets = &self.packets[first..first + pending.item_count as usize];
                for (offset, packet) in packets.iter().enumerate() {
                    for lane in 0..LANES {
                        let Some(shape) = packet.shape(lane) else {
                            break;
                        };
                        let (valid, t, u, v) = shape_across(&batch, &shape, t_best);
                        // Rays outside this leaf's box may be tested too (the
                        // lanes cost nothing more): any hit found is a true one.
                        let closer = valid & open;
                        t_best = closer.select(t, t_best);
                        u_best = closer.select(u, u_best);
                        v_best = closer.select(v, v_best);
                        let id = ((first + offset) * LANES + lane) as u32;
                        id_best = closer.select(f32x16::splat(Float::from_bits(id)), id_best);
                    }
                }
                continue;
            }
            if reached.count_ones() <= FEW_RAYS {
                // A node costs the batch about what it costs one ray: a ray alone
                // here goes down this subtree by itself, nearest first, from its
                // closest hit so far, and stays in the batch for the rest.
                for lane in lanes_of(reached) {
                    let mut t_max = t_best.as_array()[lane];
                    let ray = &rays[lane];
                    let lanes = PacketRay::new(ray);
                    let mut closest = None;
                    self.wide.walk_ordered_from(
                        pending.index,
                        &RayQuery::new(ray),
                        &mut t_max,
                        &self.packets,
                        |first, count, t_max| {
                            self.nearest_in_leaf(&lanes, first, count, t_max, &mut closest);
                            false
                        },
                    );
                    if let Some((packet, packet_lane, hit)) = closest {
                        t_best.as_mut_array()[lane] = hit.t;
                        u_best.as_mut_array()[lane] = hit.u;
                        v_best.as_mut_array()[lane] = hit.v;
                        id_best.as_mut_array()[lane] =
                            Float::from_bits(packet * LANES as u32 + packet_lane as u32);
                    }
                }
                continue;
            }
            let node = &self.wide.nodes[pending.index as usize];
            if ordered {
                push_met_children::<true>(
                    &batch,
                    node,
                    t_best,
                    reached,
                    &mut stack,
                    &mut stack_len,
                );
            } else {
                push_met_children::<false>(
                    &batch,
                    node,
                    t_best,
                    reached,
                    &mut stack,
                    &mut stack_len,
                );
            }
        }
        let (t, u, v, id) = (
            t_best.to_array(),
            u_best.to_array(),
            v_best.to_array(),
            id_best.to_array(),
        );
        for lane in lanes_of(active) {
            let id = id[lane].to_bits();
            if id == u32::MAX {
                hits[lane] = None;
                continue;
            }
            let hit = PrimHit {
                t: t[lane],
                u: u[lane],
                v: v[lane],
            };
            let (packet, lane_in_packet) = (id / LANES as u32, (id % LANES as u32) as usize);
            // As `Scene::intersect`: texture coordinates and bumps in textured scenes
            // only. Each arm stores its hit straight into the slot: a hit made apart
            // (field by field, on the stack) and then moved in whole was read back
            // in 64-byte loads over its narrow stores, which cannot be forwarded (a
            // quarter of this function's time on the Cornell box).
            if !self.second_phase {
                hits[lane] =
                    Some(self.hit_details_inline(&rays[lane], packet, lane_in_packet, hit));
            } else {
                hits[lane] =
                    Some(self.textured_hit_details(&rays[lane], packet, lane_in_packet, hit));
            }
        }
    }

    /// The rays `rays[i]` of `active` that something blocks before `t_max[i]`, as a
    /// bit mask.
    pub fn occluded_batch(&self, rays: &[Ray; BATCH], t_max: &[Float; BATCH], active: u32) -> u32 {
        if self.ray_by_ray
            || self.instances.is_some()
            || active.count_ones() <= FEW_RAYS
            || self.wide.nodes.is_empty()
        {
            return lanes_of(active)
                .filter(|&lane| self.occluded(&rays[lane], t_max[lane]))
                .fold(0, |mask, lane| mask | 1 << lane);
        }
        let batch = RayPacket::new(rays);
        let limit = f32x16::from(*t_max);
        let mut blocked = 0u32;
        let mut stack = [const { MaybeUninit::<Pending>::uninit() }; STACK_SIZE];
        stack[0].write(Pending {
            index: 0,
            item_count: 0,
            rays: active,
            t_enter: 0.0,
        });
        let mut stack_len = 1;
        while stack_len > 0 && blocked != active {
            stack_len -= 1;
            // SAFETY: entries below `stack_len` were written before.
            let pending = unsafe { stack[stack_len].assume_init() };
            let open = pending.rays & !blocked;
            if open == 0 {
                continue;
            }
            if pending.item_count > 0 {
                let first = pending.index as usize;
                let packets = &self.packets[first..first + pending.item_count as usize];
                'packets: for packet in packets {
                    for lane in 0..LANES {
                        let Some(shape) = packet.shape(lane) else {
                            break;
                        };
                        let valid = shape_across(&batch, &shape, limit).0;
                        blocked |= valid.to_bitmask() & open;
                        if open & !blocked == 0 {
                            break 'packets;
                        }
                    }
                }
                continue;
            }
            if open.count_ones() <= FEW_RAYS {
                // As in `intersect_batch`: a ray alone here goes down this subtree
                // by itself.
                for lane in lanes_of(open) {
                    let ray = &rays[lane];
                    let lanes = PacketRay::new(ray);
                    let mut reach = t_max[lane];
                    let found = self.wide.walk_any_from(
                        pending.index,
                        &RayQuery::new(ray),
                        &mut reach,
                        &self.packets,
                        |first, count, reach| self.blocker_in_leaf(&lanes, first, count, *reach),
                    );
                    if found {
                        blocked |= 1 << lane;
                    }
                }
                continue;
            }
            let node = &self.wide.nodes[pending.index as usize];
            push_met_children::<false>(&batch, node, limit, open, &mut stack, &mut stack_len);
        }
        blocked & active
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::BvhParams;
    use crate::formats;
    use crate::math::Vec3;
    use rand::{Rng, SeedableRng};
    use std::fmt::Write;
    use std::path::Path;

    fn cornell() -> Scene {
        let path = Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tests/data/path/cornell.obj"
        ));
        Scene::build(formats::load_mesh(path).unwrap(), &BvhParams::default())
    }

    /// A cloud of `n` random triangles and a few spheres in the unit cube: a tree of
    /// many nodes, where batches split and leave rays to be traced alone.
    fn soup(n: usize, seed: u64) -> Scene {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let mut obj = String::new();
        for i in 0..n {
            let centre: [f32; 3] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
            for _ in 0..3 {
                let [x, y, z] = centre.map(|c| c + rng.random_range(-0.15..0.15));
                writeln!(obj, "v {x} {y} {z}").unwrap();
            }
            writeln!(obj, "f {} {} {}", 3 * i + 1, 3 * i + 2, 3 * i + 3).unwrap();
        }
        for _ in 0..5 {
            let [x, y, z]: [f32; 3] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
            writeln!(obj, "S {x} {y} {z} {}", rng.random_range(0.05..0.3)).unwrap();
        }
        let description = formats::parse_obj(obj.as_bytes(), Path::new("soup.obj")).unwrap();
        Scene::build(description, &BvhParams::default())
    }

    fn random_rays(rng: &mut rand::rngs::StdRng, spread: Float) -> [Ray; BATCH] {
        std::array::from_fn(|_| {
            let origin = Vec3::new(
                rng.random_range(-spread..spread),
                rng.random_range(0.1..1.9),
                rng.random_range(-spread..spread),
            );
            let dir = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            Ray::new(origin, dir)
        })
    }

    /// Batches of scattered rays, some lanes inactive, find the hits single rays
    /// find (the same distances bit for bit, as each lane computes what the scalar
    /// kernels compute) and block exactly the shadow rays single rays say are blocked.
    /// Returns how many rays were tested and how many hit.
    fn check_against_single_rays(scene: &Scene, seed: u64, spread: Float) -> (usize, usize) {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let (mut tested, mut hit) = (0, 0);
        for round in 0..300 {
            let rays = random_rays(&mut rng, spread);
            let active: u32 = match round % 4 {
                0 => 0xFFFF,
                1 => rng.random_range(0..0x10000),
                2 => 1 << rng.random_range(0..16),
                _ => rng.random_range(0..0x10000) & rng.random_range(0..0x10000),
            };
            let mut hits = [None; BATCH];
            scene.intersect_batch(&rays, active, &mut hits);
            for lane in 0..BATCH {
                let single = scene.intersect(&rays[lane]);
                if active >> lane & 1 == 0 {
                    assert_eq!(hits[lane], None, "inactive lane {lane} was written");
                    continue;
                }
                tested += 1;
                let bits = |hit: Option<Hit>| hit.map(|h| (h.t.to_bits(), h.uv.to_array()));
                assert_eq!(bits(hits[lane]), bits(single), "round {round}, lane {lane}");
                hit += usize::from(single.is_some());
            }
            let t_max: [Float; BATCH] = std::array::from_fn(|_| rng.random_range(0.01..3.0));
            let blocked = scene.occluded_batch(&rays, &t_max, active);
            for lane in 0..BATCH {
                let expected = active >> lane & 1 != 0 && scene.occluded(&rays[lane], t_max[lane]);
                assert_eq!(
                    blocked >> lane & 1 != 0,
                    expected,
                    "round {round}, lane {lane}"
                );
            }
        }
        (tested, hit)
    }

    /// The Cornell box's walls with texture coordinates and a 2x2 `map_Kd`, written
    /// to a temporary folder: a textured scene, whose hits carry `uv`.
    fn textured_box() -> Scene {
        let folder = tempfile::tempdir().unwrap();
        let image =
            image::RgbImage::from_fn(2, 2, |x, y| image::Rgb([40 + 100 * (x ^ y) as u8; 3]));
        image.save(folder.path().join("checker.png")).unwrap();
        std::fs::write(
            folder.path().join("box.mtl"),
            "newmtl checker\nKd 1 1 1\nmap_Kd checker.png\n",
        )
        .unwrap();
        let mut obj = String::from("mtllib box.mtl\nusemtl checker\n");
        for [x, y, z] in [
            [-1, 0, -1],
            [1, 0, -1],
            [1, 0, 1],
            [-1, 0, 1],
            [-1, 2, -1],
            [1, 2, -1],
            [1, 2, 1],
            [-1, 2, 1],
        ] {
            writeln!(obj, "v {x} {y} {z}").unwrap();
        }
        obj.push_str("vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n");
        for [a, b, c, d] in [
            [1, 4, 3, 2],
            [5, 6, 7, 8],
            [1, 2, 6, 5],
            [1, 5, 8, 4],
            [2, 3, 7, 6],
        ] {
            writeln!(obj, "f {a}/1 {b}/2 {c}/3 {d}/4").unwrap();
        }
        obj.push_str("S 0.3 0.4 0.1 0.3\n");
        let path = folder.path().join("box.obj");
        std::fs::write(&path, obj).unwrap();
        Scene::build(formats::load_mesh(&path).unwrap(), &BvhParams::default())
    }

    #[test]
    fn batches_find_what_single_rays_find_in_a_textured_scene() {
        let scene = textured_box();
        assert!(scene.second_phase, "the scene is not textured");
        let (tested, hit) = check_against_single_rays(&scene, 4, 0.9);
        assert!(tested > 2_000 && hit * 10 > tested * 8, "{hit} of {tested}");
    }

    /// A quad whose corners are red, green, blue and white (OBJ's `v x y z r g b`)
    /// and no maps: its hits take the second phase for their colour, yet the scene
    /// keeps no texture coordinate indices.
    #[test]
    fn coloured_scenes_without_maps_keep_no_texture_coordinates_yet_colour_their_hits() {
        let obj =
            "v -1 0 -1 1 0 0\nv 1 0 -1 0 1 0\nv 1 0 1 0 0 1\nv -1 0 1 1 1 1\nf 1 2 3\nf 1 3 4\n";
        let description = formats::parse_obj(obj.as_bytes(), Path::new("quad.obj")).unwrap();
        let scene = Scene::build(description, &BvhParams::default());
        assert!(scene.second_phase);
        assert!(
            scene.prim_texcoords.is_empty(),
            "{} texture coordinate indices",
            scene.prim_texcoords.len()
        );
        // Straight down onto the first triangle's centroid: a third each of red,
        // green and blue, through batches and single rays alike.
        let rays: [Ray; BATCH] =
            std::array::from_fn(|_| Ray::new(Vec3::new(1.0 / 3.0, 1.0, -1.0 / 3.0), Vec3::NEG_Y));
        let mut hits = [None; BATCH];
        scene.intersect_batch(&rays, 0xFFFF, &mut hits);
        for hit in hits.into_iter().chain([scene.intersect(&rays[0])]) {
            let colour = hit.expect("a hit").colour;
            let error = (colour - Vec3::splat(1.0 / 3.0)).abs().max_element();
            assert!(error < 1e-5, "{colour}");
        }
    }

    #[test]
    fn batches_find_what_single_rays_find_in_a_small_scene() {
        let (tested, hit) = check_against_single_rays(&cornell(), 1, 0.9);
        // Inside the box (open at the front) most rays hit something.
        assert!(tested > 2_000 && hit * 10 > tested * 8, "{hit} of {tested}");
    }

    /// Traces `rays` (the lanes in `active`) as a closest-hit batch and, up to
    /// `t_max`, as an any-hit batch, and asserts that each lane's hit distance (and
    /// its texture coordinates if `compare_uv`) and blocker are the single ray's, bit
    /// for bit; returns how many lanes were tested, hit something and were blocked.
    fn batch_against_single_rays(
        scene: &Scene,
        rays: &[Ray; BATCH],
        t_max: &[Float; BATCH],
        active: u32,
        compare_uv: bool,
        round: usize,
    ) -> (usize, usize, usize) {
        let mut hits = [None; BATCH];
        scene.intersect_batch(rays, active, &mut hits);
        let blocked = scene.occluded_batch(rays, t_max, active);
        let (mut tested, mut hit, mut blocked_count) = (0, 0, 0);
        for lane in lanes_of(active) {
            let single = scene.intersect(&rays[lane]);
            let bits = |hit: Option<Hit>| {
                hit.map(|h| (h.t.to_bits(), compare_uv.then(|| h.uv.to_array())))
            };
            assert_eq!(bits(hits[lane]), bits(single), "round {round}, lane {lane}");
            let expected = scene.occluded(&rays[lane], t_max[lane]);
            assert_eq!(
                blocked >> lane & 1 != 0,
                expected,
                "round {round}, lane {lane}"
            );
            tested += 1;
            hit += usize::from(single.is_some());
            blocked_count += usize::from(expected);
        }
        (tested, hit, blocked_count)
    }

    /// Bundles of rays from one point in directions a little apart, as a pixel's
    /// bounce rays off a rough metal are: they share the top of the tree and part
    /// deep down, so the walk orders children for several rays, skips boxes behind
    /// some rays' hits and hands rays left alone to subtree walks that start from
    /// their hits so far. Every lane's hit must be the single ray's, bit for bit.
    #[test]
    fn bundles_that_part_deep_in_the_tree_find_what_single_rays_find() {
        let scene = soup(3_000, 5);
        let mut rng = rand::rngs::StdRng::seed_from_u64(6);
        let (mut tested, mut hit, mut blocked_count) = (0, 0, 0);
        for round in 0..400 {
            let origin = Vec3::new(
                rng.random_range(-1.2..1.2),
                rng.random_range(-1.2..1.2),
                rng.random_range(-1.2..1.2),
            );
            let axis = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            let spread = [0.02, 0.1, 0.4][round % 3];
            let rays: [Ray; BATCH] = std::array::from_fn(|_| {
                let jitter = Vec3::new(
                    rng.random_range(-spread..spread),
                    rng.random_range(-spread..spread),
                    rng.random_range(-spread..spread),
                );
                Ray::new(origin, (axis.normalize_or(Vec3::X) + jitter).normalize())
            });
            let active = if round % 2 == 0 {
                0xFFFF
            } else {
                rng.random_range(1..0x10000)
            };
            let t_max: [Float; BATCH] = std::array::from_fn(|_| rng.random_range(0.05..3.0));
            let counts = batch_against_single_rays(&scene, &rays, &t_max, active, true, round);
            (tested, hit, blocked_count) =
                (tested + counts.0, hit + counts.1, blocked_count + counts.2);
        }
        assert!(hit > tested / 4 && hit < tested, "{hit} of {tested}");
        assert!(
            blocked_count > tested / 10 && blocked_count < tested,
            "{blocked_count} of {tested}"
        );
    }

    /// A 6x6x6 grid of axis-aligned cubes of side 0.1, 0.2 apart (12 triangles
    /// each): box faces at exactly the coordinates rays are aimed along.
    fn cube_grid() -> Scene {
        let mut obj = String::new();
        let mut corners = 0;
        for (i, j, k) in (0..216).map(|n| (n % 6, n / 6 % 6, n / 36)) {
            let low = [i, j, k].map(|c| c as Float * 0.2);
            for corner in 0..8 {
                let [x, y, z] = [0, 1, 2].map(|a| low[a] + 0.1 * (corner >> a & 1) as Float);
                writeln!(obj, "v {x} {y} {z}").unwrap();
            }
            for [a, b, c, d] in [
                [0, 2, 3, 1],
                [4, 5, 7, 6],
                [0, 1, 5, 4],
                [2, 6, 7, 3],
                [0, 4, 6, 2],
                [1, 3, 7, 5],
            ] {
                let [a, b, c, d] = [a, b, c, d].map(|v| corners + v + 1);
                writeln!(obj, "f {a} {b} {c}\nf {a} {c} {d}").unwrap();
            }
            corners += 8;
        }
        let description = formats::parse_obj(obj.as_bytes(), Path::new("grid.obj")).unwrap();
        Scene::build(description, &BvhParams::default())
    }

    /// Coherent bundles, as a pixel's samples are, find the hits and blockers single
    /// rays find, where the batch walks many nodes together and rays meet boxes at
    /// their faces and edges: a pixel's camera rays (one origin, directions a pixel
    /// apart), shadow rays (origins spread over a patch, aimed at one point), rays
    /// grazing the cubes' faces (origins on a face's plane, directions in it) and
    /// rays passing just by the cubes' edges, inside or outside; with shadow
    /// distances that let near cubes block some rays early, so the any-hit walk goes
    /// on with the rest. (It also guards any bounds of the whole batch tried in the
    /// walk: full mode's packet [`crate::bvh`] frustum, tried here, failed it when
    /// its entry bound took one end of the reciprocals' range only.)
    #[test]
    fn coherent_bundles_find_what_single_rays_find() {
        let scene = cube_grid();
        assert!(scene.bvh_summary().wide_nodes > 20);
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let (mut tested, mut hit, mut blocked_count) = (0, 0, 0);
        let jitter = |rng: &mut rand::rngs::StdRng, spread: Float| {
            Vec3::from_array(std::array::from_fn(|_| rng.random_range(-spread..=spread)))
        };
        for round in 0..600 {
            // Towards the grid's far corner, from outside it or within it.
            let origin = Vec3::new(
                rng.random_range(-0.6..0.4),
                rng.random_range(-0.6..0.4),
                rng.random_range(-0.6..0.4),
            );
            let aim = Vec3::new(
                rng.random_range(0.6..1.2),
                rng.random_range(0.6..1.2),
                rng.random_range(0.6..1.2),
            );
            let rays: [Ray; BATCH] = match round % 4 {
                0 => std::array::from_fn(|_| {
                    Ray::new(origin, (aim - origin + jitter(&mut rng, 2e-3)).normalize())
                }),
                1 => std::array::from_fn(|_| {
                    let from = origin + jitter(&mut rng, 0.05);
                    Ray::new(from, (aim - from).normalize())
                }),
                2 => {
                    // On the plane of a face (y = 0.2 j or 0.2 j + 0.1), running in it.
                    let y = (rng.random_range(0..12) as Float) * 0.1;
                    let base = Vec3::new(origin.x, 0.0, origin.z);
                    std::array::from_fn(|_| {
                        let d =
                            Vec3::new(rng.random_range(0.5..1.0), 0.0, rng.random_range(0.5..1.0));
                        Ray::new(base + Vec3::new(0.0, y, 0.0), d.normalize())
                    })
                }
                _ => std::array::from_fn(|_| {
                    // Just inside or just outside a cube's edge: two coordinates off
                    // face planes by 1e-4. (Exactly at an edge the two faces' hits
                    // differ by rounding alone, and a walk may cull the box of the
                    // nearer face after finding the farther: which one it keeps
                    // depends on its order, batch or not.)
                    let [i, j, k] = [0; 3].map(|_| {
                        let off = if rng.random_bool(0.5) { 1e-4 } else { -1e-4 };
                        rng.random_range(0..12) as Float * 0.1 + off
                    });
                    let target = [
                        Vec3::new(i, j, rng.random_range(0.0..1.1)),
                        Vec3::new(i, rng.random_range(0.0..1.1), k),
                        Vec3::new(rng.random_range(0.0..1.1), j, k),
                    ][rng.random_range(0..3)];
                    let from = Vec3::new(-0.5, -0.5, -0.5) + jitter(&mut rng, 0.01);
                    Ray::new(from, (target - from).normalize())
                }),
            };
            let active = if round % 3 == 2 {
                rng.random_range(0x20..0x10000) | 0x1F
            } else {
                0xFFFF
            };
            let t_max: [Float; BATCH] = std::array::from_fn(|_| rng.random_range(0.05..2.0));
            // Distances alone, bit for bit: at an edge two faces may tie, and which
            // one wins may depend on the order the leaves were met in.
            let counts = batch_against_single_rays(&scene, &rays, &t_max, active, false, round);
            (tested, hit, blocked_count) =
                (tested + counts.0, hit + counts.1, blocked_count + counts.2);
        }
        // Many rays hit and some (not all) shadow rays were blocked.
        assert!(hit > tested / 3 && hit < tested, "{hit} of {tested}");
        assert!(
            blocked_count > tested / 10 && blocked_count < tested * 9 / 10,
            "{blocked_count} of {tested}"
        );
    }

    #[test]
    fn batches_find_what_single_rays_find_in_a_deep_tree() {
        let scene = soup(3_000, 2);
        assert!(scene.bvh_summary().wide_nodes > 50);
        let (tested, hit) = check_against_single_rays(&scene, 3, 1.0);
        assert!(hit > 300 && hit < tested, "{hit} of {tested}");
    }
}
