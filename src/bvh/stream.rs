//! Walks of a whole stream of up to 64 rays at once, as Embree's stream traversal
//! answers incoherent queries: the stream goes down the tree together, each node
//! visited once with the set of rays that reached it, as a bit per ray. Rays that
//! start near one another share most of the nodes they visit (bounce rays from
//! neighbouring pixels share the tree's top and the surface they leave), so a node's
//! memory is waited for once per stream rather than once per ray, and the box tests
//! of the rays that reached it run back to back, each ray against the node's eight
//! children with its own walk's slab test, bit for bit: independent work the
//! processor overlaps, where one ray's walk is a chain of steps that each wait for
//! the one before.

use std::mem::MaybeUninit;

use wide::{f32x8, u32x8, u64x8};

use super::wide::{ChildRef, STACK_SIZE, WIDTH, WideBvh, WideNode, WideRay, sort_far_to_near};
use super::{CLOSEST_CULL_MARGIN, PREFETCH_LINES, RayQuery};
use crate::math::{Float, nearest_in_mask};
use crate::memory::prefetch_lines;

/// Most rays one stream walk takes: one bit each of a `u64`. On the dragon's bounce
/// rays, streams of 32 or 128 rays were 4-10% slower, of 16 rays 16%.
pub const STREAM_RAYS: usize = 64;

/// Bit `i` in lane `i`: spreads a node's hit mask over one lane per child.
const SLOT_BITS: u64x8 = u64x8::new([1, 2, 4, 8, 16, 32, 64, 128]);
/// The same for 32-bit lanes.
const SLOT_BITS_32: u32x8 = u32x8::new([1, 2, 4, 8, 16, 32, 64, 128]);

/// The rays of a stream walk that have reached one node or leaf, a bit each.
type Rays = u64;

impl WideBvh {
    /// Whether each ray of `rays` (at most [`STREAM_RAYS`]) meets something within
    /// its reach `t_max[i]`: bit `i` of the answer for ray `i`, the answer of
    /// [`WideBvh::walk_any`] for that ray. `leaf(ray, first_item, item_count, t_max)`
    /// tests leaf items for ray `rays[ray]` and returns whether one blocks it; that
    /// ray then leaves the stream.
    ///
    /// Each ray reaches the leaves its own walk reaches, in another order, and the
    /// answers are booleans, so they are the same; a ray may test leaves its own walk
    /// would not have reached before it stopped.
    ///
    /// # Panics
    /// If `rays` holds more than [`STREAM_RAYS`] rays, or `t_max` differs from it in
    /// length.
    pub fn walk_stream_any<T, F>(
        &self,
        rays: &[RayQuery],
        t_max: &[Float],
        items: &[T],
        mut leaf: F,
    ) -> u64
    where
        F: FnMut(usize, u32, u32, Float) -> bool,
    {
        assert!(rays.len() <= STREAM_RAYS, "at most {STREAM_RAYS} rays");
        assert_eq!(rays.len(), t_max.len(), "one reach per ray");
        if self.nodes.is_empty() || rays.is_empty() {
            return 0;
        }
        let mut blocked: Rays = 0;
        // Nodes and leaves still to visit, each with the rays that reached it. The
        // walk goes depth first, so the stack holds at most `WIDTH - 1` pending
        // siblings per level, as one ray's does.
        let mut stack = [const { MaybeUninit::<(ChildRef, Rays)>::uninit() }; STACK_SIZE];
        stack[0].write((ROOT, every_ray(rays.len())));
        let mut stack_len = 1;
        while stack_len > 0 {
            stack_len -= 1;
            // SAFETY: every entry below `stack_len` was written before.
            let (current, reached) = unsafe { stack[stack_len].assume_init() };
            let mut waiting = reached & !blocked;
            if waiting == 0 {
                continue;
            }
            if current.item_count > 0 {
                while waiting != 0 {
                    let ray = waiting.trailing_zeros() as usize;
                    waiting &= waiting - 1;
                    if leaf(ray, current.index, current.item_count, t_max[ray]) {
                        blocked |= 1 << ray;
                    }
                }
                continue;
            }
            let node = &self.nodes[current.index as usize];
            let slot_rays = rays_per_child::<false>(node, rays, t_max, waiting, |_, _, _| {});
            // Interior children go on the stack first, leaves last: a stream's leaves
            // are tested first, their items asked for now, and any ray they block
            // leaves the stream before it goes down elsewhere (as `walk_any`).
            let met = met_slots(&slot_rays);
            let leaves = met & node.leaf_slots();
            for slots in [met & !leaves, leaves] {
                let mut slots = slots;
                while slots != 0 {
                    let slot = slots.trailing_zeros() as usize;
                    slots &= slots - 1;
                    let child = node.child_ref(slot);
                    if child.item_count > 0 {
                        prefetch_lines(
                            items.as_ptr().wrapping_add(child.index as usize),
                            PREFETCH_LINES,
                        );
                    } else {
                        self.prefetch_node(child);
                    }
                    debug_assert!(stack_len < STACK_SIZE);
                    stack[stack_len].write((child, slot_rays[slot]));
                    stack_len += 1;
                }
            }
        }
        blocked
    }

    /// The closest hits of `rays` (at most [`STREAM_RAYS`]), each within its reach
    /// `t_max[i]`, which the leaf test lowers: [`WideBvh::walk_ordered`] for a
    /// stream. `leaf(ray, first_item, item_count, entry, t_max)` tests leaf items for
    /// ray `rays[ray]`, which entered the leaf's box at distance `entry`.
    ///
    /// At each node, every ray that reached it tests the leaves among the children
    /// it meets right away, nearest first, their items asked for as soon as one ray
    /// meets them; the interior children go on the stack nearest first by the mean
    /// entry distance of the rays that meet them. A ray's leaves therefore come in
    /// another order than in its own walk: where two hits lie at exactly the same
    /// distance, or a hit lies nearer than the box entry of its leaf (the triangle
    /// test's edge tolerance reaches a hair outside a triangle's box), its own walk
    /// may keep another hit, and a caller after its answers bit for bit must trace
    /// such a ray again on its own (`entry` tells it). So that the caller sees such
    /// hits, boxes are entered up to [`CLOSEST_CULL_MARGIN`] times a ray's `t_max`,
    /// as in the closest-hit packet walk: every leaf single-ray traversal could
    /// test is tested, unless a hit falls short of its box by more than that.
    ///
    /// # Panics
    /// If `rays` holds more than [`STREAM_RAYS`] rays, or `t_max` differs from it in
    /// length.
    pub fn walk_stream_closest<T, F>(
        &self,
        rays: &[RayQuery],
        t_max: &mut [Float],
        items: &[T],
        mut leaf: F,
    ) where
        F: FnMut(usize, u32, u32, Float, &mut Float),
    {
        assert!(rays.len() <= STREAM_RAYS, "at most {STREAM_RAYS} rays");
        assert_eq!(rays.len(), t_max.len(), "one reach per ray");
        if self.nodes.is_empty() || rays.is_empty() {
            return;
        }
        // Interior nodes still to visit, with the rays that reached them.
        let mut stack = [const { MaybeUninit::<(ChildRef, Rays)>::uninit() }; STACK_SIZE];
        stack[0].write((ROOT, every_ray(rays.len())));
        let mut stack_len = 1;
        // Each ray's children met at the current node, and its entry distances.
        let mut met_by = [0u8; STREAM_RAYS];
        let mut entries = [[0.0; WIDTH]; STREAM_RAYS];
        while stack_len > 0 {
            stack_len -= 1;
            // SAFETY: every entry below `stack_len` was written before.
            let (current, reached) = unsafe { stack[stack_len].assume_init() };
            let node = &self.nodes[current.index as usize];
            let mut entry_sums = f32x8::ZERO;
            let leaf_slots = node.leaf_slots();
            // Leaves whose items were asked for: each as soon as a ray meets it, so
            // that the items are on their way during the other rays' box tests.
            let mut asked = 0;
            let slot_rays =
                rays_per_child::<true>(node, rays, t_max, reached, |ray, hits, t_enter| {
                    met_by[ray] = hits as u8;
                    entries[ray] = t_enter.to_array();
                    let met = (u32x8::splat(hits) & SLOT_BITS_32).simd_ne(u32x8::ZERO);
                    entry_sums += t_enter & bytemuck::cast::<u32x8, f32x8>(met);
                    let new = hits & leaf_slots & !asked;
                    asked |= new;
                    node.prefetch_leaves(new, items);
                });
            let met = met_slots(&slot_rays);
            let leaves = met & leaf_slots;
            // Far first, so that the nearest is on top (`ChildRef::index` holds the
            // slot while sorting).
            let mut interior = [(ROOT, 0.0); WIDTH];
            let mut interior_count = 0;
            let sums = entry_sums.to_array();
            let mut slots = met & !leaves;
            while slots != 0 {
                let slot = slots.trailing_zeros() as usize;
                slots &= slots - 1;
                let mean = sums[slot] / slot_rays[slot].count_ones() as Float;
                interior[interior_count] = (
                    ChildRef {
                        index: slot as u32,
                        item_count: 0,
                    },
                    mean,
                );
                interior_count += 1;
            }
            sort_far_to_near(&mut interior[..interior_count]);
            for &(slot, _) in &interior[..interior_count] {
                let slot = slot.index as usize;
                let child = ChildRef {
                    index: node.child(slot),
                    item_count: 0,
                };
                self.prefetch_node(child);
                debug_assert!(stack_len < STACK_SIZE);
                stack[stack_len].write((child, slot_rays[slot]));
                stack_len += 1;
            }
            if leaves == 0 {
                continue;
            }
            let mut waiting = reached;
            while waiting != 0 {
                let ray = waiting.trailing_zeros() as usize;
                waiting &= waiting - 1;
                let entry = &entries[ray];
                let mut left = u32::from(met_by[ray]) & leaves;
                while let Some(nearest) = nearest_in_mask(left, entry) {
                    left &= !(1 << nearest);
                    if entry[nearest] <= t_max[ray] * CLOSEST_CULL_MARGIN {
                        let (first, count) = (node.child(nearest), node.item_count[nearest]);
                        leaf(ray, first, count, entry[nearest], &mut t_max[ray]);
                    }
                }
            }
        }
    }
}

/// The root node, where every walk starts.
const ROOT: ChildRef = ChildRef {
    index: 0,
    item_count: 0,
};

/// The mask of the first `count` rays of a stream.
fn every_ray(count: usize) -> Rays {
    Rays::MAX >> (STREAM_RAYS - count)
}

/// The rays of `waiting` that meet each child of `node` within their reach `t_max`
/// (entering before it; if `CLOSEST`, at most [`CLOSEST_CULL_MARGIN`] times it, as
/// the closest-hit packet walk, so as to see every hit whose answer in single-ray
/// traversal could depend on the order of the leaves): one slab test per ray, whose
/// hit mask and entry distances also go to `each(ray, hits, t_enter)`.
#[inline(always)]
fn rays_per_child<const CLOSEST: bool>(
    node: &WideNode,
    rays: &[RayQuery],
    t_max: &[Float],
    mut waiting: Rays,
    mut each: impl FnMut(usize, u32, f32x8),
) -> [Rays; WIDTH] {
    // Lane `i` holds the rays that meet child `i`: one masked OR per ray rather than
    // one per child it meets.
    let mut slot_rays = u64x8::ZERO;
    while waiting != 0 {
        let ray = waiting.trailing_zeros() as usize;
        waiting &= waiting - 1;
        let reach = if CLOSEST {
            t_max[ray] * CLOSEST_CULL_MARGIN
        } else {
            t_max[ray]
        };
        let (hits, t_enter) = WideRay::new(&rays[ray]).hit_children::<CLOSEST>(node, reach);
        let met = (u64x8::splat(u64::from(hits)) & SLOT_BITS).simd_ne(u64x8::ZERO);
        slot_rays |= met & u64x8::splat(1 << ray);
        each(ray, hits, t_enter);
    }
    slot_rays.to_array()
}

/// Bit `i` set if some ray meets child `i`.
fn met_slots(slot_rays: &[Rays; WIDTH]) -> u32 {
    slot_rays
        .iter()
        .enumerate()
        .fold(0, |met, (slot, &rays)| met | u32::from(rays != 0) << slot)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::{Bvh, BvhParams};
    use crate::math::{Aabb, Ray, Vec3};
    use rand::{Rng, SeedableRng};

    /// Random boxes thicker and larger than the wide BVH tests' (so that rays from
    /// one region meet, share and are blocked by many), a tree over them with leaves
    /// of up to four, and the boxes in the tree's leaf order.
    fn random_tree(count: usize, seed: u64) -> (WideBvh, Vec<Aabb>) {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let boxes: Vec<Aabb> = (0..count)
            .map(|_| {
                let min = Vec3::new(
                    rng.random_range(-10.0..10.0),
                    rng.random_range(-10.0..10.0),
                    rng.random_range(-10.0..10.0),
                );
                let size = Vec3::new(rng.random_range(0.0..1.5), rng.random_range(0.0..1.5), 0.1);
                Aabb {
                    min,
                    max: min + size,
                }
            })
            .collect();
        let (bvh, order) = Bvh::build(&boxes, &BvhParams::default());
        let wide = WideBvh::collapse(&bvh, 4, &BvhParams::default());
        (wide, order.iter().map(|&i| boxes[i as usize]).collect())
    }

    /// Rays from points near one another (as bounces from neighbouring pixels
    /// leave a surface), in every direction.
    fn rays_near(count: usize, seed: u64) -> Vec<Ray> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let centre = Vec3::new(
            rng.random_range(-5.0..5.0),
            rng.random_range(-5.0..5.0),
            rng.random_range(-5.0..5.0),
        );
        (0..count)
            .map(|_| {
                let offset = Vec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                );
                let dir = Vec3::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                );
                Ray::new(centre + offset, dir)
            })
            .collect()
    }

    /// Whether `ray` enters `bounds` at a distance in `[0, t_max)`.
    fn meets(ray: &Ray, bounds: &Aabb, t_max: Float) -> bool {
        let mut t_enter: Float = 0.0;
        let mut t_exit = Float::INFINITY;
        for axis in 0..3 {
            let inv = 1.0 / ray.dir[axis];
            let a = (bounds.min[axis] - ray.origin[axis]) * inv;
            let b = (bounds.max[axis] - ray.origin[axis]) * inv;
            t_enter = t_enter.max(a.min(b));
            t_exit = t_exit.min(a.max(b));
        }
        t_enter <= t_exit && t_enter < t_max
    }

    /// Each ray of a stream is found blocked exactly when its own any-hit walk
    /// finds it blocked, for full and ragged streams and reaches from zero to
    /// unlimited.
    #[test]
    fn stream_walks_answer_as_single_walks() {
        let mut counts = [0; 2];
        for (boxes, seed) in [(1, 1), (40, 2), (3000, 3)] {
            let (bvh, leaf_boxes) = random_tree(boxes, seed);
            for n in [1, 2, 17, STREAM_RAYS] {
                let rays = rays_near(n, seed * 100 + n as u64);
                let reach: Vec<Float> = (0..n)
                    .map(|i| [Float::INFINITY, 0.0, 2.0, 8.0][i % 4])
                    .collect();
                let queries: Vec<RayQuery> = rays.iter().map(RayQuery::new).collect();
                let blocker = |ray: &Ray, first: u32, count: u32, t_max: Float| {
                    leaf_boxes[first as usize..(first + count) as usize]
                        .iter()
                        .any(|b| meets(ray, b, t_max))
                };
                let answers = bvh.walk_stream_any(&queries, &reach, &leaf_boxes, |r, f, c, t| {
                    blocker(&rays[r], f, c, t)
                });
                for (i, (query, ray)) in queries.iter().zip(&rays).enumerate() {
                    let mut t_max = reach[i];
                    let alone = bvh.walk_any(query, &mut t_max, &leaf_boxes, |f, c, t| {
                        blocker(ray, f, c, *t)
                    });
                    assert_eq!(
                        answers >> i & 1 != 0,
                        alone,
                        "{boxes} boxes, ray {i} of {n}"
                    );
                    counts[usize::from(alone)] += 1;
                }
                let past = answers.checked_shr(n as u32).unwrap_or(0);
                assert_eq!(past, 0, "no answer past the rays");
            }
        }
        assert!(counts.iter().all(|&c| c > 20), "{counts:?}");
    }

    /// The stream visits each leaf once, for all the rays that reached it: the
    /// rays' tests of one leaf come one after another, not ray by ray.
    #[test]
    fn a_stream_tests_each_leaf_for_all_its_rays_at_once() {
        let (bvh, leaf_boxes) = random_tree(3000, 4);
        let rays = rays_near(STREAM_RAYS, 5);
        let queries: Vec<RayQuery> = rays.iter().map(RayQuery::new).collect();
        let mut visits: Vec<(u32, usize)> = Vec::new();
        bvh.walk_stream_any(
            &queries,
            &[Float::INFINITY; STREAM_RAYS],
            &leaf_boxes,
            |r, f, _, _| {
                visits.push((f, r));
                false
            },
        );
        // Runs of the same leaf, and whether a leaf comes back after another.
        let mut runs: Vec<(u32, usize)> = Vec::new();
        for &(leaf, _) in &visits {
            match runs.last_mut() {
                Some((last, rays)) if *last == leaf => *rays += 1,
                _ => runs.push((leaf, 1)),
            }
        }
        let mut leaves: Vec<u32> = runs.iter().map(|&(leaf, _)| leaf).collect();
        let run_count = leaves.len();
        leaves.sort_unstable();
        leaves.dedup();
        assert_eq!(leaves.len(), run_count, "a leaf was visited twice");
        assert!(
            runs.iter().filter(|&&(_, rays)| rays > 4).count() > 10,
            "too few leaves shared by the rays: {runs:?}"
        );
        // Nothing blocks: every ray met its own walk's leaves.
        for (i, query) in queries.iter().enumerate() {
            let mut own = Vec::new();
            let mut reach = Float::INFINITY;
            bvh.walk_any(query, &mut reach, &leaf_boxes, |f, _, _| {
                own.push(f);
                false
            });
            let mut met: Vec<u32> = visits.iter().filter(|v| v.1 == i).map(|v| v.0).collect();
            own.sort_unstable();
            met.sort_unstable();
            assert_eq!(met, own, "ray {i}");
        }
    }
}
