//! An 8-wide BVH collapsed from the binary one, for traversal: each node holds the
//! boxes of up to eight children in structure-of-arrays form, so one ray meets all
//! eight boxes in a handful of 8-lane SIMD operations (the layout of Embree's BVH8 and
//! obvhs's `Bvh8`/tinybvh's `BVH8_CPU`, built the same way: by pulling the largest
//! grandchildren of a binary node up into it).
//!
//! Like [`Bvh`](super::Bvh), the wide BVH knows nothing of geometry: a leaf is a range of "items"
//! that the caller created for a range of primitives (the scene turns them into SIMD
//! triangle packets), and traversal hands that range to a closure.

use std::mem::MaybeUninit;

use glam::Vec4;
use wide::{f32x8, i32x8};

use super::{BvhInvariantError, BvhParams, MAX_DEPTH};
use crate::math::{Aabb, Float, Ray, Vec3};
use crate::memory::{prefetch_aligned_lines, prefetch_lines};

/// Children per node: one 256-bit AVX register of `f32`.
pub const WIDTH: usize = 8;

/// Slack on the exit distance of the slab test so that rounding in `(min - o) / d`
/// never culls a box the ray grazes: pbrt's `1 + 2 * gamma(3)`.
pub(super) const SLAB_EXIT_SLACK: Float = 1.0 + 2.0 * 3.0 * (Float::EPSILON * 0.5);

/// One node: eight child boxes as planes `[min x, max x, min y, max y, min z, max z]`
/// of eight lanes each, then what each child is. 256 bytes, four cache lines.
///
/// An unused slot has an inverted box (`min = +inf`, `max = -inf`), which the slab test
/// rejects for every ray, so traversal never needs to know how many slots are used.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub struct WideNode {
    /// Box planes of the children, lane `i` belonging to child `i`.
    pub planes: [f32x8; 6],
    /// Interior child or unused slot: index of its node (0 if unused). Leaf child:
    /// index of its first item with the top bit ([`LEAF_LINK`]) set, so that one
    /// comparison with the node count tells a node from a leaf (and checks the
    /// node's index). [`WideNode::child`] is the index without that bit.
    pub link: [u32; WIDTH],
    /// Interior child or unused slot: 0. Leaf child: number of items, at least 1.
    pub item_count: [u32; WIDTH],
}

const _: () = assert!(std::mem::size_of::<WideNode>() == 256);

/// The bit of a [`WideNode::link`] that marks a leaf.
pub const LEAF_LINK: u32 = 1 << 31;

impl WideNode {
    pub(super) const EMPTY: WideNode = WideNode {
        planes: [
            f32x8::splat(Float::INFINITY),
            f32x8::splat(Float::NEG_INFINITY),
            f32x8::splat(Float::INFINITY),
            f32x8::splat(Float::NEG_INFINITY),
            f32x8::splat(Float::INFINITY),
            f32x8::splat(Float::NEG_INFINITY),
        ],
        link: [0; WIDTH],
        item_count: [0; WIDTH],
    };

    /// Slot `slot`'s node index, or its first item if it is a leaf.
    #[inline(always)]
    pub fn child(&self, slot: usize) -> u32 {
        self.link[slot] & !LEAF_LINK
    }

    /// What slot `slot` points at, its index without the leaf bit.
    #[inline(always)]
    pub(super) fn child_ref(&self, slot: usize) -> ChildRef {
        ChildRef {
            index: self.child(slot),
            item_count: self.item_count[slot],
        }
    }

    /// Points slot `slot` at node `index`.
    ///
    /// # Panics
    /// If `index` has the top bit set (no tree has 2^31 nodes).
    pub fn set_node(&mut self, slot: usize, index: u32) {
        assert!(index < LEAF_LINK, "node index {index} too large");
        (self.link[slot], self.item_count[slot]) = (index, 0);
    }

    /// Makes slot `slot` a leaf of items `first..first + count`.
    ///
    /// # Panics
    /// If `count` is 0 or `first` has the top bit set (no scene has 2^31 items).
    pub fn set_leaf(&mut self, slot: usize, first: u32, count: u32) {
        assert!(first < LEAF_LINK, "first item {first} too large");
        assert!(count > 0, "a leaf of no items");
        (self.link[slot], self.item_count[slot]) = (first | LEAF_LINK, count);
    }

    /// The box of child slot `slot` (inverted for an unused slot).
    pub fn child_bounds(&self, slot: usize) -> Aabb {
        let plane = |p: usize| self.planes[p].as_array()[slot];
        Aabb {
            min: Vec3::new(plane(0), plane(2), plane(4)),
            max: Vec3::new(plane(1), plane(3), plane(5)),
        }
    }

    /// Bit `i` set if slot `i` is a leaf: the links' top bits.
    #[inline(always)]
    pub(super) fn leaf_slots(&self) -> u32 {
        i32x8::from(bytemuck::cast::<[u32; WIDTH], [i32; WIDTH]>(self.link))
            .simd_lt(i32x8::ZERO)
            .to_bitmask()
    }

    /// Asks for the memory of the items of each leaf slot in `slots`, so that they
    /// are on their way together rather than one cache miss after another as the
    /// leaf tests read them.
    #[inline(always)]
    pub(super) fn prefetch_leaves<T>(&self, mut slots: u32, items: &[T]) {
        while slots != 0 {
            let slot = slots.trailing_zeros() as usize;
            slots &= slots - 1;
            prefetch_lines(
                items.as_ptr().wrapping_add(self.child(slot) as usize),
                PREFETCH_LINES,
            );
        }
    }

    pub(super) fn set_child_bounds(&mut self, slot: usize, bounds: Aabb) {
        let values = [
            bounds.min.x,
            bounds.max.x,
            bounds.min.y,
            bounds.max.y,
            bounds.min.z,
            bounds.max.z,
        ];
        for (plane, value) in self.planes.iter_mut().zip(values) {
            plane.as_mut_array()[slot] = value;
        }
    }
}

/// The wide BVH: node 0 is the root (when there is any primitive).
#[derive(Clone, Debug, Default)]
pub struct WideBvh {
    /// All nodes.
    pub nodes: Vec<WideNode>,
}

/// Most entries the traversal stack can hold: at most `WIDTH - 1` pending siblings per
/// level, and the wide tree is no deeper than the binary one it came from.
pub(crate) const STACK_SIZE: usize = (WIDTH - 1) * MAX_DEPTH + 1;

/// Entries of a single ray's walk stack: [`STACK_SIZE`] rounded up to a power of two,
/// so that the stack's length is kept below it by a mask rather than checked at every
/// push and pop (a tree deeper than the bound, which no build makes, wraps the stack
/// and ends the walk early, but reads nothing unwritten).
const WALK_STACK: usize = STACK_SIZE.next_power_of_two();

/// A single ray's walk stack: pending children and their entry distances.
type WalkStack = [MaybeUninit<(Link, Float)>; WALK_STACK];

/// What a slot or stack entry points at: a node (`item_count == 0`) or a leaf's items.
#[derive(Clone, Copy, Debug)]
pub(super) struct ChildRef {
    pub(super) index: u32,
    pub(super) item_count: u32,
}

/// What a single ray's walk keeps of a child: its [`WideNode::link`] (a leaf's with
/// the leaf bit) and item count.
#[derive(Clone, Copy, Debug)]
struct Link {
    link: u32,
    item_count: u32,
}

impl WideBvh {
    /// The `(first, count)` item range of every leaf, in node and slot order: the
    /// order [`WideBvh::assign_leaf_items`] expects.
    pub fn leaf_items(&self) -> Vec<(u32, u32)> {
        self.nodes
            .iter()
            .flat_map(|node| {
                (0..WIDTH)
                    .filter(|&slot| node.item_count[slot] > 0)
                    .map(|slot| (node.child(slot), node.item_count[slot]))
            })
            .collect()
    }

    /// The SAH cost of the tree as [`Bvh::sah_cost`](super::Bvh::sah_cost) prices
    /// the binary one: each node's box area relative to the root's times
    /// `params.traversal_cost`, plus each leaf's times its `leaf_tests(item_count)`
    /// times `params.intersection_cost` (leaves' items are the caller's: primitives
    /// straight after the collapse, the scene's packets after it).
    pub fn sah_cost(&self, params: &BvhParams, leaf_tests: impl Fn(u32) -> Float) -> f64 {
        let node_area = |node: &WideNode| {
            let bounds = (0..WIDTH)
                .map(|slot| node.child_bounds(slot))
                .fold(Aabb::EMPTY, Aabb::union);
            f64::from(bounds.half_area())
        };
        let Some(root) = self.nodes.first() else {
            return 0.0;
        };
        let root_area = node_area(root);
        if root_area <= 0.0 {
            return 0.0;
        }
        let leaf_cost = |node: &WideNode| -> f64 {
            (0..WIDTH)
                .filter(|&slot| node.item_count[slot] > 0)
                .map(|slot| {
                    f64::from(node.child_bounds(slot).half_area())
                        * f64::from(leaf_tests(node.item_count[slot]))
                })
                .sum()
        };
        let cost: f64 = self
            .nodes
            .iter()
            .map(|node| {
                node_area(node) * f64::from(params.traversal_cost)
                    + leaf_cost(node) * f64::from(params.intersection_cost)
            })
            .sum();
        cost / root_area
    }

    /// Points leaf `i` (in [`WideBvh::leaf_items`] order) at items
    /// `first_items[i]..first_items[i + 1]`, so `first_items` holds one entry more
    /// than there are leaves, and the ranges must be non-empty.
    ///
    /// # Panics
    /// If `first_items` has the wrong length or a range is empty.
    pub fn assign_leaf_items(&mut self, first_items: &[u32]) {
        let mut leaf = 0;
        for node in &mut self.nodes {
            for slot in 0..WIDTH {
                if node.item_count[slot] > 0 {
                    let (first, end) = (first_items[leaf], first_items[leaf + 1]);
                    assert!(end > first, "leaf {leaf} has no items");
                    node.set_leaf(slot, first, end - first);
                    leaf += 1;
                }
            }
        }
        assert_eq!(
            leaf + 1,
            first_items.len(),
            "one first item per leaf, plus the end"
        );
    }

    /// Checks every invariant traversal relies on: each node reached exactly once
    /// from the root, unused slots empty (inverted box, no items), each item
    /// `0..item_count` in exactly one leaf and inside that leaf's box
    /// (`item_bounds(item)`), and each child node's slots inside its parent's slot.
    ///
    /// # Errors
    /// The first broken invariant found.
    pub fn validate<F>(&self, item_count: usize, item_bounds: F) -> Result<(), BvhInvariantError>
    where
        F: Fn(u32) -> Aabb,
    {
        let fail = |msg: String| Err(BvhInvariantError(msg));
        if self.nodes.is_empty() {
            return match item_count {
                0 => Ok(()),
                n => fail(format!("no nodes for {n} items")),
            };
        }
        let mut node_seen = vec![false; self.nodes.len()];
        let mut item_seen = vec![false; item_count];
        // (node, the box of the slot that points at it)
        let mut pending = vec![(0usize, None)];
        while let Some((index, parent_box)) = pending.pop() {
            match node_seen.get_mut(index) {
                Some(seen) if !*seen => *seen = true,
                _ => return fail(format!("node {index} reached twice or out of range")),
            }
            let node = &self.nodes[index];
            for slot in 0..WIDTH {
                let bounds = node.child_bounds(slot);
                let unused = bounds.min.cmpgt(bounds.max).any();
                if unused {
                    if node.item_count[slot] != 0 {
                        return fail(format!("node {index}: empty slot {slot} has items"));
                    }
                    continue;
                }
                if let Some(parent) = parent_box
                    && !Aabb::contains(&parent, &bounds)
                {
                    return fail(format!(
                        "node {index}: slot {slot} sticks out of its parent"
                    ));
                }
                let (child, items) = (node.child(slot), node.item_count[slot]);
                if (items > 0) != (node.link[slot] & LEAF_LINK != 0) {
                    return fail(format!("node {index}: slot {slot}'s leaf bit is wrong"));
                }
                if items == 0 {
                    pending.push((child as usize, Some(bounds)));
                    continue;
                }
                for item in child..child.saturating_add(items) {
                    match item_seen.get_mut(item as usize) {
                        Some(seen) if !*seen => *seen = true,
                        _ => return fail(format!("item {item} in two leaves or out of range")),
                    }
                    if !bounds.contains(&item_bounds(item)) {
                        return fail(format!("item {item} outside its leaf in node {index}"));
                    }
                }
            }
        }
        if let Some(unseen) = node_seen.iter().position(|&s| !s) {
            return fail(format!("node {unseen} unreachable"));
        }
        if let Some(missing) = item_seen.iter().position(|&s| !s) {
            return fail(format!("item {missing} in no leaf"));
        }
        Ok(())
    }

    /// Visits the leaves the ray may hit within `t_max`, nearest box first (by entry
    /// distance), skipping any whose box starts beyond the current `t_max`.
    /// `leaf(first_item, item_count, t_max)` may shrink `t_max` and returns `true`
    /// to stop the walk; returns whether it stopped. `items` are what the leaves'
    /// item ranges index: the walk reads none of them, but asks the processor for
    /// the first item of every leaf the ray meets as soon as the leaf's parent is
    /// tested, and for every node it puts on the stack, so that large scenes, whose
    /// nodes and leaves do not fit in the caches, wait less for memory (incoherent
    /// rays on the dragon: 1.09x, one thread).
    #[inline(always)]
    pub fn walk_ordered<T, F>(
        &self,
        ray: &RayQuery,
        t_max: &mut Float,
        items: &[T],
        leaf: F,
    ) -> bool
    where
        F: FnMut(u32, u32, &mut Float) -> bool,
    {
        self.walk::<T, F>(0, ray, t_max, items, leaf)
    }

    /// [`WideBvh::walk_ordered`] of the subtree under node `node` alone: a batch
    /// walk hands a ray that has left its batch's company the rest of its way
    /// down from where it is, rather than from the root.
    #[inline(always)]
    pub fn walk_ordered_from<T, F>(
        &self,
        node: u32,
        ray: &RayQuery,
        t_max: &mut Float,
        items: &[T],
        leaf: F,
    ) -> bool
    where
        F: FnMut(u32, u32, &mut Float) -> bool,
    {
        self.walk::<T, F>(node, ray, t_max, items, leaf)
    }

    /// [`WideBvh::walk_any`] of the subtree under node `node` alone, as
    /// [`WideBvh::walk_ordered_from`].
    #[inline(always)]
    pub fn walk_any_from<T, F>(
        &self,
        node: u32,
        ray: &RayQuery,
        t_max: &mut Float,
        items: &[T],
        leaf: F,
    ) -> bool
    where
        F: FnMut(u32, u32, &mut Float) -> bool,
    {
        self.walk_unordered(node, ray, t_max, items, leaf)
    }

    /// As [`WideBvh::walk_ordered`] for any-hit queries, where the first blocker found
    /// ends the walk and sorting by distance would be wasted: at each node the leaves
    /// the ray meets come before the interior children, whose memory arrives
    /// meanwhile; otherwise in slot order.
    #[inline(always)]
    pub fn walk_any<T, F>(&self, ray: &RayQuery, t_max: &mut Float, items: &[T], leaf: F) -> bool
    where
        F: FnMut(u32, u32, &mut Float) -> bool,
    {
        self.walk_unordered(0, ray, t_max, items, leaf)
    }

    /// Asks for the memory of a child put on the stack, if it is a node, so that it
    /// is on its way while the walk goes down its nearer siblings (a leaf's items
    /// were asked for already). Without a branch, as whether a child is a leaf is
    /// as good as random: a leaf's slot points at the node of the same index, which
    /// is fetched for nothing. Large scenes' nodes do not fit in the caches, and an
    /// incoherent ray's next node is otherwise a cache miss the walk waits for.
    #[inline(always)]
    pub(super) fn prefetch_node(&self, child: ChildRef) {
        // A node is 64-byte aligned: its address needs no rounding to a line.
        prefetch_aligned_lines(
            self.nodes.as_ptr().wrapping_add(child.index as usize),
            PREFETCH_LINES,
        );
    }

    #[inline(always)]
    fn walk<T, F>(
        &self,
        start: u32,
        ray: &RayQuery,
        t_max: &mut Float,
        items: &[T],
        mut leaf: F,
    ) -> bool
    where
        F: FnMut(u32, u32, &mut Float) -> bool,
    {
        if self.nodes.is_empty() {
            return false;
        }
        // Uninitialised: zeroing 10 KB per ray would cost more than many node visits.
        let mut stack: WalkStack = [const { MaybeUninit::uninit() }; WALK_STACK];
        let mut walk = Walk::new(ray, start);
        loop {
            match self.step::<T, F>(&mut walk, &mut stack, t_max, items, &mut leaf) {
                Step::Going => {}
                Step::Stopped => return true,
                Step::Finished => return false,
            }
        }
    }

    /// The any-hit walk of [`WideBvh::walk_any`] from node `start`. A node's leaves
    /// the ray meets are tested where they are met, in slot order, before any of
    /// its interior children (whose memory is asked for first, so that it arrives
    /// meanwhile); the first interior child is visited next and the others wait on
    /// a stack of node indices alone, as no distance orders or culls them: the
    /// reach only changes if a leaf lowers it, and then the boxes met later are
    /// tested against the lower one.
    #[inline(always)]
    fn walk_unordered<T, F>(
        &self,
        start: u32,
        ray: &RayQuery,
        t_max: &mut Float,
        items: &[T],
        mut leaf: F,
    ) -> bool
    where
        F: FnMut(u32, u32, &mut Float) -> bool,
    {
        // Uninitialised, as the ordered walk's.
        let mut stack: [MaybeUninit<u32>; WALK_STACK] =
            [const { MaybeUninit::uninit() }; WALK_STACK];
        let mut stack_len = 0usize;
        let slabs = WideRay::new(ray);
        let mut limit = AnyHitLimit::new(*t_max);
        let mut current = start;
        loop {
            // Only nodes are visited (leaves are tested at their parent); the
            // comparison also checks the index (an empty tree has none).
            if let Some(node) = self.nodes.get(current as usize) {
                let hits = slabs.hit_children_within(node, &limit);
                if hits != 0 {
                    let leaves = hits & node.leaf_slots();
                    let mut interior = hits & !leaves;
                    node.prefetch_leaves(leaves, items);
                    if interior != 0 {
                        let first = interior.trailing_zeros() as usize;
                        interior &= interior - 1;
                        current = node.link[first];
                        if leaves != 0 {
                            self.prefetch_node_index(current);
                        }
                        while interior != 0 {
                            let slot = interior.trailing_zeros() as usize;
                            interior &= interior - 1;
                            let child = node.link[slot];
                            self.prefetch_node_index(child);
                            // SAFETY: `stack_len < WALK_STACK` always (kept so by
                            // the mask below).
                            unsafe { stack.get_unchecked_mut(stack_len) }.write(child);
                            stack_len = (stack_len + 1) & (WALK_STACK - 1);
                        }
                    }
                    let mut pending = leaves;
                    while pending != 0 {
                        let slot = pending.trailing_zeros() as usize;
                        pending &= pending - 1;
                        if leaf(node.child(slot), node.item_count[slot], t_max) {
                            return true;
                        }
                        limit = AnyHitLimit::new(*t_max);
                    }
                    if hits != leaves {
                        continue;
                    }
                }
            }
            if stack_len == 0 {
                return false;
            }
            stack_len -= 1;
            // SAFETY: `stack_len < WALK_STACK`, and every entry below it was written
            // before.
            current = unsafe { stack.get_unchecked(stack_len).assume_init() };
        }
    }

    /// Asks for the memory of node `index`.
    #[inline(always)]
    fn prefetch_node_index(&self, index: u32) {
        prefetch_aligned_lines(
            self.nodes.as_ptr().wrapping_add(index as usize),
            PREFETCH_LINES,
        );
    }

    /// Puts `child`, met at distance `t_enter`, on the walk's stack, and asks for
    /// its memory.
    #[inline(always)]
    fn push(&self, walk: &mut Walk, stack: &mut WalkStack, child: Link, t_enter: Float) {
        debug_assert!(walk.stack_len < STACK_SIZE);
        // As `prefetch_node`: a leaf's link without its leaf bit (dropped by the
        // doubling in 32 bits) points at the node of its first item's index.
        prefetch_aligned_lines(
            self.nodes
                .as_ptr()
                .cast::<u8>()
                .wrapping_add(child.link.wrapping_mul(2) as usize * (size_of::<WideNode>() / 2)),
            PREFETCH_LINES,
        );
        // SAFETY: `stack_len < WALK_STACK` always (kept so by the mask below).
        unsafe { stack.get_unchecked_mut(walk.stack_len) }.write((child, t_enter));
        walk.stack_len = (walk.stack_len + 1) & (WALK_STACK - 1);
    }

    /// [`WideBvh::push`] of the children of the slots in `slots`, in slot order.
    #[inline(always)]
    fn push_all(
        &self,
        walk: &mut Walk,
        stack: &mut WalkStack,
        mut slots: u32,
        child: impl Fn(usize) -> Link,
        t_enter: &[Float; WIDTH],
    ) {
        while slots != 0 {
            let slot = slots.trailing_zeros() as usize;
            slots &= slots - 1;
            self.push(walk, stack, child(slot), t_enter[slot]);
        }
    }

    /// One step of a walk: visits its current node or leaf, then takes the next
    /// child to visit, nearest first, from the node's children or the
    /// stack.
    #[inline(always)]
    fn step<T, F>(
        &self,
        walk: &mut Walk,
        stack: &mut WalkStack,
        t_max: &mut Float,
        items: &[T],
        leaf: &mut F,
    ) -> Step
    where
        F: FnMut(u32, u32, &mut Float) -> bool,
    {
        let current = walk.current;
        // A leaf's link is beyond every node's index (the leaf bit): one comparison
        // tells a node from a leaf and checks the node's index.
        if let Some(node) = self.nodes.get(current.link as usize) {
            let (mut hits, t_enter) = walk.slabs.hit_children::<false>(node, *t_max);
            if hits != 0 {
                let child = |slot: usize| Link {
                    link: node.link[slot],
                    item_count: node.item_count[slot],
                };
                // The items of every leaf hit are asked for at once, the nearest's
                // too: they are on their way together rather than one cache miss
                // after another as the leaf test reads them.
                node.prefetch_leaves(hits & node.leaf_slots(), items);
                let t_enter = t_enter.as_array();
                let first = hits.trailing_zeros() as usize;
                hits &= hits - 1;
                if hits == 0 {
                    walk.current = child(first);
                } else {
                    let second = hits.trailing_zeros() as usize;
                    hits &= hits - 1;
                    if hits == 0 {
                        // Two children, the most common case after one: no sort.
                        let (near, far) = if t_enter[first] <= t_enter[second] {
                            (first, second)
                        } else {
                            (second, first)
                        };
                        self.push(walk, stack, child(far), t_enter[far]);
                        walk.current = child(near);
                    } else {
                        // Three or more: push all, then sort the pushed run so that
                        // the nearest is on top, and take it.
                        let run_start = walk.stack_len;
                        hits |= (1 << first) | (1 << second);
                        self.push_all(walk, stack, hits, child, t_enter);
                        // SAFETY: entries `run_start..stack_len` were written just
                        // above (a stack wrapped by a tree too deep makes this range
                        // empty or inverted, which the indexing refuses).
                        let run = unsafe {
                            &mut *(&mut stack[run_start..walk.stack_len] as *mut [_]
                                as *mut [(Link, Float)])
                        };
                        sort_far_to_near(run);
                        walk.current = run[run.len() - 1].0;
                        walk.stack_len -= 1;
                    }
                }
                return Step::Going;
            }
        } else {
            debug_assert!(current.link & LEAF_LINK != 0 && current.item_count > 0);
            if leaf(current.link & !LEAF_LINK, current.item_count, t_max) {
                return Step::Stopped;
            }
        }
        // Pop the next pending child that can still hold a closer hit.
        loop {
            if walk.stack_len == 0 {
                return Step::Finished;
            }
            walk.stack_len -= 1;
            // SAFETY: `stack_len < WALK_STACK`, and every entry below it was written
            // before.
            let (next, t_entry) = unsafe { stack.get_unchecked(walk.stack_len).assume_init() };
            if t_entry < *t_max {
                walk.current = next;
                return Step::Going;
            }
        }
    }
}

/// Where one ray's walk is: its slab test, the node or leaf it visits next, and how
/// many entries of its stack are pending.
#[derive(Clone, Copy)]
struct Walk {
    slabs: WideRay,
    current: Link,
    stack_len: usize,
}

impl Walk {
    /// A walk of `ray` from node `start` (0: the root).
    #[inline(always)]
    fn new(ray: &RayQuery, start: u32) -> Walk {
        Walk {
            slabs: WideRay::new(ray),
            current: Link {
                link: start,
                item_count: 0,
            },
            stack_len: 0,
        }
    }
}

/// What a walk's step left to do.
#[derive(Clone, Copy)]
enum Step {
    /// More to visit.
    Going,
    /// The leaf closure asked to stop.
    Stopped,
    /// Nothing left that can hold a hit.
    Finished,
}

/// Lines a walk asks for ahead: a node's four, or all of a 160-byte packet of
/// triangles (the first of a leaf's one or two; three to five lines were measured
/// alike on the dragon).
pub(crate) const PREFETCH_LINES: usize = 4;

/// Insertion sort by decreasing entry distance: at most eight entries, mostly two or
/// three, where it beats any general sort.
#[inline(always)]
pub(super) fn sort_far_to_near<R: Copy>(run: &mut [(R, Float)]) {
    for i in 1..run.len() {
        let entry = run[i];
        let mut j = i;
        while j > 0 && run[j - 1].1 < entry.1 {
            run[j] = run[j - 1];
            j -= 1;
        }
        run[j] = entry;
    }
}

/// Smallest direction component the slab test divides by. A zero component would
/// give an infinite reciprocal and `0 * inf = NaN` for a ray lying in a slab's plane;
/// with this floor the product is 0 and such a ray counts as inside the (closed) box,
/// as it should (obvhs's `safe_inverse` does the same).
pub(super) const MIN_DIR_COMPONENT: Float = 1e-30;

/// A ray prepared for box tests: origin and the reciprocal of its direction,
/// computed once per ray.
#[derive(Clone, Copy, Debug)]
pub struct RayQuery {
    /// Ray origin; the fourth lane is 0.
    pub origin: Vec4,
    /// `1 / dir` per component, finite; the fourth lane is 0.
    pub inv_dir: Vec4,
}

impl RayQuery {
    /// Prepares `ray` for traversal: the three reciprocals in one 4-lane division
    /// (the same values, bit for bit, as three scalar divisions).
    #[inline]
    pub fn new(ray: &Ray) -> RayQuery {
        let dir = ray.dir.extend(1.0);
        let floor = Vec4::splat(MIN_DIR_COMPONENT);
        let safe = Vec4::select(dir.abs().cmplt(floor), floor.copysign(dir), dir);
        let inv_dir = safe.recip().truncate();
        debug_assert!(inv_dir.is_finite());
        RayQuery {
            origin: ray.origin.extend(0.0),
            inv_dir: inv_dir.extend(0.0),
        }
    }
}

/// A ray set up for eight-box slab tests: origin and reciprocal direction in every
/// lane, and for each axis which plane the ray meets first.
#[derive(Clone, Copy)]
pub(super) struct WideRay {
    origin: [f32x8; 3],
    /// `-1 / dir` per axis: negative where the ray meets the min plane
    /// (`planes[2 * axis]`) first, positive where it meets the max plane first.
    neg_inv_dir: [f32x8; 3],
}

impl WideRay {
    #[inline(always)]
    pub(super) fn new(ray: &RayQuery) -> WideRay {
        let [x, y, z, _] = ray.origin.to_array();
        let [u, v, w, _] = ray.inv_dir.to_array();
        WideRay::from_parts([x, y, z], [u, v, w])
    }

    /// From a ray's origin and the reciprocal of its direction, as [`RayQuery::new`]
    /// computes it.
    #[inline(always)]
    pub(super) fn from_parts(origin: [Float; 3], inv_dir: [Float; 3]) -> WideRay {
        WideRay {
            origin: [0, 1, 2].map(|a| f32x8::splat(origin[a])),
            neg_inv_dir: [0, 1, 2].map(|a| f32x8::splat(-inv_dir[a])),
        }
    }

    /// Bit `i` set if the ray meets child `i`'s box with an entry distance `< reach`
    /// (`<= reach` if `INCLUSIVE`), and each child's entry distance. Taking each
    /// axis's near plane by the sign of the direction (rather than min/max of both)
    /// makes inverted boxes miss.
    #[inline(always)]
    pub(super) fn hit_children<const INCLUSIVE: bool>(
        &self,
        node: &WideNode,
        reach: Float,
    ) -> (u32, f32x8) {
        let mut t_enter = f32x8::ZERO;
        // No distance is NaN (`inv_dir` is finite and non-zero), so the first axis's
        // far distance is the minimum of it and infinity.
        let mut t_exit = f32x8::ZERO;
        for axis in 0..3 {
            // `(origin - plane) * -inv_dir`: the same rounding as `(plane - origin) *
            // inv_dir`, negation being exact (only a zero's sign can differ, which no
            // comparison sees), and the plane can be the operand read from memory.
            // Not one fused `plane * inv_dir - origin * inv_dir`: that is no faster
            // here (measured) and loses precision to cancellation when the origin is
            // far from the world origin. Both planes at fixed offsets, the near one
            // picked by the sign of the direction: no plane index to keep or reload.
            let neg_inv_dir = self.neg_inv_dir[axis];
            let t_min = (self.origin[axis] - node.planes[2 * axis]) * neg_inv_dir;
            let t_max = (self.origin[axis] - node.planes[2 * axis + 1]) * neg_inv_dir;
            t_enter = t_enter.fast_max(select_by_sign(neg_inv_dir, t_min, t_max));
            let far = select_by_sign(neg_inv_dir, t_max, t_min);
            t_exit = if axis == 0 { far } else { t_exit.fast_min(far) };
        }
        let t_exit = t_exit * f32x8::splat(SLAB_EXIT_SLACK);
        let reach = f32x8::splat(reach);
        let within = if INCLUSIVE {
            t_enter.simd_le(reach)
        } else {
            t_enter.simd_lt(reach)
        };
        ((t_enter.simd_le(t_exit) & within).to_bitmask(), t_enter)
    }

    /// [`WideRay::hit_children`]'s bits (not inclusive) for an any-hit walk, which
    /// needs no entry distances out: arranged for a short chain of dependent
    /// operations rather than few operations (as Embree's test is), as the walk
    /// waits for each node's test before it can read the next node, with the same
    /// bits as the plain form `max(0, near) <= min(far) * slack && max(0, near) <
    /// t_max`: the entry is the maximum of the near distances' bits as integers
    /// (one-cycle operations), and the exit is not reduced at all: each far
    /// distance is scaled and compared on its own, in parallel, as `min(a, b) * s`
    /// rounds to `min(a * s, b * s)` (rounding is monotonic, `s > 0`). (The
    /// closest-hit walks keep the plain form: measured faster there, 2026-11-29.)
    #[inline(always)]
    pub(super) fn hit_children_within(&self, node: &WideNode, limit: &AnyHitLimit) -> u32 {
        let mut near = [f32x8::ZERO; 3];
        let mut far = [f32x8::ZERO; 3];
        for axis in 0..3 {
            // `(origin - plane) * -inv_dir`: the same rounding as `(plane - origin) *
            // inv_dir`, negation being exact (only a zero's sign can differ, which no
            // comparison sees), and the plane can be the operand read from memory.
            // Not one fused `plane * inv_dir - origin * inv_dir`: that is no faster
            // here (measured) and loses precision to cancellation when the origin is
            // far from the world origin. Both planes at fixed offsets, the near one
            // picked by the sign of the direction: no plane index to keep or reload.
            let neg_inv_dir = self.neg_inv_dir[axis];
            let t_min = (self.origin[axis] - node.planes[2 * axis]) * neg_inv_dir;
            let t_max = (self.origin[axis] - node.planes[2 * axis + 1]) * neg_inv_dir;
            near[axis] = select_by_sign(neg_inv_dir, t_min, t_max);
            far[axis] = select_by_sign(neg_inv_dir, t_max, t_min);
        }
        // No distance is NaN (`inv_dir` is finite and non-zero). Non-negative floats
        // order as their bits do as signed integers and negative ones lie below
        // them all, so with +0 among them the integer maximum is the float maximum
        // (up to a zero's sign).
        let t_enter = max_bits(max_bits(near[0], near[1]), max_bits(near[2], f32x8::ZERO));
        let slack = f32x8::splat(SLAB_EXIT_SLACK);
        let inside = (t_enter.simd_le(far[0] * slack) & t_enter.simd_le(far[1] * slack))
            & (t_enter.simd_le(far[2] * slack) & t_enter.simd_le(limit.0));
        inside.to_bitmask()
    }
}

/// The lane-wise maximum of `a` and `b` taken as signed integers: the float
/// maximum where either is non-negative (see [`WideRay::hit_children_within`]).
#[inline(always)]
fn max_bits(a: f32x8, b: f32x8) -> f32x8 {
    bytemuck::cast(bytemuck::cast::<f32x8, i32x8>(a).max(bytemuck::cast::<f32x8, i32x8>(b)))
}

/// The reach of an any-hit walk's slab tests, `t_max`, as the greatest distance
/// strictly below it in every lane: `t_enter < t_max` is `t_enter <= limit` (no
/// distance is NaN), made once a walk rather than once a node.
#[derive(Clone, Copy)]
pub(super) struct AnyHitLimit(f32x8);

impl AnyHitLimit {
    #[inline(always)]
    pub(super) fn new(t_max: Float) -> AnyHitLimit {
        AnyHitLimit(f32x8::splat(t_max.next_down()))
    }
}

/// Per lane, `if_negative` where `sign`'s sign bit is set, else `otherwise`; `sign`
/// is never zero or NaN here. One `vblendvps` on AVX, which reads only the sign bit,
/// so no mask needs to be computed or kept per ray.
#[inline(always)]
fn select_by_sign(sign: f32x8, if_negative: f32x8, otherwise: f32x8) -> f32x8 {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
    {
        use std::arch::x86_64::{__m256, _mm256_blendv_ps};
        let [sign, if_negative, otherwise]: [__m256; 3] =
            [sign, if_negative, otherwise].map(bytemuck::cast);
        // SAFETY: the `avx` target feature is enabled at compile time.
        bytemuck::cast(unsafe { _mm256_blendv_ps(otherwise, if_negative, sign) })
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx")))]
    {
        sign.simd_lt(f32x8::ZERO).select(if_negative, otherwise)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::Bvh;
    use crate::bvh::BvhParams;
    use rand::{Rng, SeedableRng};

    fn random_boxes(count: usize, seed: u64) -> Vec<Aabb> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        (0..count)
            .map(|_| {
                let min = Vec3::new(
                    rng.random_range(-10.0..10.0),
                    rng.random_range(-10.0..10.0),
                    rng.random_range(-10.0..10.0),
                );
                let size = Vec3::new(rng.random_range(0.0..1.0), rng.random_range(0.0..1.0), 0.0);
                Aabb {
                    min,
                    max: min + size,
                }
            })
            .collect()
    }

    /// Collapses with one item per primitive, validates, and checks that leaves are
    /// no bigger than asked (unless a binary leaf was) and that renumbering items
    /// works.
    fn check_collapse(count: usize, max_leaf_prims: u32, seed: u64) {
        let boxes = random_boxes(count, seed);
        let (bvh, order) = Bvh::build(&boxes, &BvhParams::default());
        let leaf_order: Vec<Aabb> = order.iter().map(|&i| boxes[i as usize]).collect();
        let wide = WideBvh::collapse(&bvh, max_leaf_prims, &BvhParams::default());
        let leaves = wide.leaf_items();
        wide.validate(count, |prim| leaf_order[prim as usize])
            .unwrap();
        // Items made per leaf (here: two per primitive) end up where the leaves point.
        let mut renumbered = wide.clone();
        let mut firsts = vec![0];
        for &(_, count) in &leaves {
            firsts.push(firsts.last().unwrap() + 2 * count);
        }
        renumbered.assign_leaf_items(&firsts);
        let expected: Vec<(u32, u32)> = firsts.windows(2).map(|w| (w[0], w[1] - w[0])).collect();
        assert_eq!(renumbered.leaf_items(), expected);
        let binary_leaf_max = bvh.nodes.iter().map(|n| n.prim_count).max().unwrap();
        assert!(
            leaves
                .iter()
                .all(|&(_, n)| n <= max_leaf_prims.max(binary_leaf_max))
        );
        // Collapsing must actually widen: far fewer nodes than the binary tree.
        if count > 1000 {
            assert!(
                wide.nodes.len() * 4 < bvh.nodes.len(),
                "{} wide nodes",
                wide.nodes.len()
            );
        }
    }

    #[test]
    fn collapse_keeps_every_invariant() {
        for (count, leaf, seed) in [
            (1, 4, 1),
            (2, 4, 2),
            (9, 4, 3),
            (100, 1, 4),
            (5000, 4, 5),
            (20_000, 8, 6),
        ] {
            check_collapse(count, leaf, seed);
        }
    }

    /// At a node whose leaves and interior children the ray both meets, the
    /// any-hit walk tests the leaves first; the closest-hit walk goes by distance.
    /// A walk from a node visits the leaves under it alone.
    #[test]
    fn any_hit_walks_visit_leaves_first_and_walks_from_a_node_stay_below_it() {
        let unit = |x: f32| Aabb {
            min: Vec3::new(x, -1.0, -1.0),
            max: Vec3::new(x + 1.0, 1.0, 1.0),
        };
        // The root: slot 0 an interior node (x in 0..1, nearer along +x), slot 1 a
        // leaf of item 0 (x in 2..3). Node 1: a leaf of item 1 in slot 0.
        let mut root = WideNode::EMPTY;
        root.set_child_bounds(0, unit(0.0));
        root.set_node(0, 1);
        root.set_child_bounds(1, unit(2.0));
        root.set_leaf(1, 0, 1);
        let mut inner = WideNode::EMPTY;
        inner.set_child_bounds(0, unit(0.0));
        inner.set_leaf(0, 1, 1);
        let bvh = WideBvh {
            nodes: vec![root, inner],
        };
        bvh.validate(2, |item| unit(if item == 0 { 2.0 } else { 0.0 }))
            .unwrap();
        let ray = RayQuery::new(&crate::math::Ray::new(Vec3::new(-1.0, 0.0, 0.0), Vec3::X));
        let items = [0u8; 2];
        // The leaves a walk visits, from the root or from node `from`.
        let visits = |ordered: bool, from: Option<u32>| {
            let mut seen = Vec::new();
            let leaf = |first: u32, _: u32, _: &mut Float| {
                seen.push(first);
                false
            };
            let mut t_max = Float::INFINITY;
            match (ordered, from) {
                (true, None) => bvh.walk_ordered(&ray, &mut t_max, &items, leaf),
                (false, None) => bvh.walk_any(&ray, &mut t_max, &items, leaf),
                (true, Some(node)) => bvh.walk_ordered_from(node, &ray, &mut t_max, &items, leaf),
                (false, Some(node)) => bvh.walk_any_from(node, &ray, &mut t_max, &items, leaf),
            };
            seen
        };
        assert_eq!(visits(false, None), [0, 1]);
        assert_eq!(visits(true, None), [1, 0]);
        // From node 1, a walk sees that node's subtree alone: its leaf of item 1,
        // not the root's leaf of item 0 that the ray also meets.
        assert_eq!(visits(false, Some(1)), [1]);
        assert_eq!(visits(true, Some(1)), [1]);
        let mut seen = Vec::new();
        bvh.walk_stream_any(&[ray], &[Float::INFINITY], &items, |_, first, _, _| {
            seen.push(first);
            false
        });
        assert_eq!(seen, [0, 1]);
    }

    #[test]
    fn inverted_boxes_of_unused_slots_miss_every_ray() {
        let node = WideNode::EMPTY;
        for dir in [
            Vec3::X,
            -Vec3::X,
            Vec3::new(1e-31, 0.0, 1.0),
            Vec3::new(-0.5, 0.5, -0.7),
        ] {
            let ray = crate::math::Ray::new(Vec3::ZERO, dir.normalize());
            let slabs = WideRay::new(&RayQuery::new(&ray));
            assert_eq!(
                slabs.hit_children::<false>(&node, Float::INFINITY).0,
                0,
                "{dir:?}"
            );
        }
    }

    /// The slab test's entry distances and hits are those of `(plane - origin) *
    /// inv_dir` with each axis's near plane chosen by the sign of the direction, for
    /// directions of either sign on every axis (and axis-parallel ones), origins inside,
    /// outside and on the boxes' planes, and degenerate (flat) boxes; the any-hit
    /// walk's test, its reach folded into the exit distance, gives the same hits.
    #[test]
    fn slab_test_matches_the_scalar_near_and_far_planes() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let mut node = WideNode::EMPTY;
        for slot in 0..WIDTH - 1 {
            let min = Vec3::new(
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
            );
            let size = if slot == 0 {
                Vec3::new(1.0, 0.0, 0.5)
            } else {
                Vec3::new(
                    rng.random_range(0.0..2.0),
                    rng.random_range(0.0..2.0),
                    rng.random_range(0.0..2.0),
                )
            };
            node.set_child_bounds(
                slot,
                Aabb {
                    min,
                    max: min + size,
                },
            );
        }
        let corner = node.child_bounds(0).min;
        let mut checked = [0u32; 2];
        for i in 0..4000 {
            let origin = if i % 4 == 0 {
                corner
            } else {
                Vec3::new(
                    rng.random_range(-4.0..4.0),
                    rng.random_range(-4.0..4.0),
                    rng.random_range(-4.0..4.0),
                )
            };
            let mut dir = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            if i % 5 == 1 {
                dir[i % 3] = 0.0;
            }
            let query = RayQuery::new(&Ray::new(origin, dir.normalize()));
            let reach = match i % 7 {
                0 => Float::INFINITY,
                1 => 0.0,
                _ => rng.random_range(0.0..6.0),
            };
            let slabs = WideRay::new(&query);
            let (hits, t_enter) = slabs.hit_children::<false>(&node, reach);
            // The any-hit walk's form, the reach folded into the exit: the same bits.
            let within = slabs.hit_children_within(&node, &AnyHitLimit::new(reach));
            assert_eq!(within, hits, "ray {i}, reach {reach}");
            for slot in 0..WIDTH {
                let bounds = node.child_bounds(slot);
                let (mut enter, mut exit) = (0.0 as Float, Float::INFINITY);
                for axis in 0..3 {
                    let inv = query.inv_dir[axis];
                    let (near, far) = if inv < 0.0 {
                        (bounds.max[axis], bounds.min[axis])
                    } else {
                        (bounds.min[axis], bounds.max[axis])
                    };
                    enter = enter.max((near - origin[axis]) * inv);
                    exit = exit.min((far - origin[axis]) * inv);
                }
                let hit = enter <= exit * SLAB_EXIT_SLACK && enter < reach;
                assert_eq!(hits >> slot & 1 == 1, hit, "ray {i}, slot {slot}");
                if hit {
                    assert_eq!(t_enter.as_array()[slot], enter, "ray {i}, slot {slot}");
                }
                checked[usize::from(hit)] += 1;
            }
        }
        assert!(checked[0] > 1000 && checked[1] > 1000, "{checked:?}");
    }
}

#[cfg(test)]
mod validate_tests {
    use super::*;
    use crate::bvh::Bvh;
    use crate::bvh::BvhParams;

    #[test]
    fn validate_catches_broken_trees() {
        let boxes: Vec<Aabb> = (0..200)
            .map(|i| {
                let min = Vec3::new(i as f32, (i % 7) as f32, 0.0);
                Aabb {
                    min,
                    max: min + Vec3::ONE,
                }
            })
            .collect();
        let (bvh, order) = Bvh::build(&boxes, &BvhParams::default());
        let leaf_order: Vec<Aabb> = order.iter().map(|&i| boxes[i as usize]).collect();
        let bounds = |item: u32| leaf_order[item as usize];
        let wide = WideBvh::collapse(&bvh, 4, &BvhParams::default());
        wide.validate(200, bounds).unwrap();
        assert!(wide.validate(201, bounds).is_err(), "a missing item");
        let mut shrunk = wide.clone();
        let slot = (0..WIDTH)
            .find(|&s| shrunk.nodes[0].item_count[s] == 0)
            .unwrap();
        shrunk.nodes[0].planes[1].as_mut_array()[slot] -= 1.0;
        assert!(
            shrunk.validate(200, bounds).is_err(),
            "a slot smaller than its contents"
        );
        // A leaf's link carries the leaf bit, a node's does not; `leaf_slots` reads it.
        for node in &wide.nodes {
            let leaves = (0..WIDTH).filter(|&s| node.item_count[s] > 0);
            assert_eq!(node.leaf_slots(), leaves.map(|s| 1 << s).sum::<u32>());
        }
        let (node, leaf) = (0..wide.nodes.len())
            .flat_map(|n| (0..WIDTH).map(move |s| (n, s)))
            .find(|&(n, s)| wide.nodes[n].item_count[s] > 0)
            .unwrap();
        let mut unmarked = wide.clone();
        unmarked.nodes[node].link[leaf] &= !LEAF_LINK;
        assert!(
            unmarked.validate(200, bounds).is_err(),
            "a leaf without its bit"
        );
        let mut dangling = wide.clone();
        let unused = (0..WIDTH).find(|&s| dangling.nodes[0].child_bounds(s).min.x.is_infinite());
        if let Some(unused) = unused {
            dangling.nodes[0].item_count[unused] = 1;
            assert!(
                dangling.validate(200, bounds).is_err(),
                "items in an unused slot"
            );
        }
    }
}
