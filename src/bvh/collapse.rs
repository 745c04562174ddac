//! Collapsing the binary BVH into the 8-wide one, on all threads, into exactly the
//! tree and node order of the sequential walk.
//!
//! Which binary nodes become a wide node's children is planned first, bottom up, in
//! the same pass that measures every subtree's primitive range: for each binary node
//! and each number of slots from one to eight, the least SAH cost of its subtree in
//! that many slots of its parent (on its own, as a leaf or a wide node, or with the
//! slots shared between its two children) and the choice that gives it (Ylitie et
//! al.'s SAH-optimal collapse). Opening the largest child first, as before, left 34%
//! of the dragon's wide nodes with two children; the plan makes 31% fewer nodes, the
//! SAH cost a little lower, and incoherent rays on the full dragon 1.05x-1.10x faster.
//!
//! The sequential walk (kept as [`WideBvh::collapse_sequential`], the reference of
//! the tests) fills the wide node of binary node `b` as planned, gives the node's
//! interior children the next indices in slot order, and goes on from a stack, last
//! child first. So the descendants of a wide node take one contiguous run of
//! indices, allocated after its own. The parallel collapse walks the top of the tree
//! the same way but leaves every binary subtree of at most `task_prims` primitives
//! to a task, which collapses it on its own into a local array of its nodes in
//! sequential order; a task's run of indices is known once the tasks before it in
//! walk order know their sizes, and one parallel copy puts every node in its place.

use std::sync::atomic::{AtomicU64, Ordering};

use rayon::prelude::*;

use super::wide::{WIDTH, WideBvh, WideNode};
use super::{Bvh, BvhNode, BvhParams};

/// Binary subtrees of at most this many primitives are collapsed as one task (or
/// more, for small trees: at least [`MIN_TASKS`] of them).
const TASK_PRIMS: u32 = 16 * 1024;

/// Tasks enough for both threads to stay busy to the end.
const MIN_TASKS: u32 = 64;

/// Trees of fewer binary nodes are collapsed sequentially.
const PARALLEL_NODES: u32 = 8 * 1024;

/// Depth of the binary tree to which the subtree ranges are measured in parallel.
const PARALLEL_RANGE_DEPTH: usize = 8;

/// The binary tree with every node's primitive range and collapse plan.
struct Binary<'a> {
    nodes: &'a [BvhNode],
    /// `(first primitive, count)` of every node's subtree, packed as
    /// `first << 32 | count`.
    ranges: Vec<AtomicU64>,
    /// Every node's [`Plan`], packed.
    plans: Vec<AtomicU64>,
    max_leaf_prims: u32,
    costs: SlotCosts,
}

impl<'a> Binary<'a> {
    /// Measures every subtree's primitive range (the builder partitions primitives in
    /// place, so each subtree's are contiguous) and plans the collapse, the top levels
    /// on all threads.
    fn new(bvh: &'a Bvh, max_leaf_prims: u32, costs: SlotCosts, parallel: bool) -> Binary<'a> {
        let nodes = &bvh.nodes[..];
        let zeroed = || {
            (0..nodes.len())
                .into_par_iter()
                .map(|_| AtomicU64::new(0))
                .collect()
        };
        let binary = Binary {
            nodes,
            ranges: zeroed(),
            plans: zeroed(),
            max_leaf_prims,
            costs,
        };
        let depth = if parallel { 0 } else { PARALLEL_RANGE_DEPTH };
        binary.measure(0, depth);
        binary
    }

    /// Measures the subtree of `index` (its primitive range) and plans its collapse:
    /// returns the range and the subtree's cheapest costs in its parent's slots.
    fn measure(&self, index: usize, depth: usize) -> ((u32, u32), Priced) {
        let node = &self.nodes[index];
        let area = f64::from(node.bounds().half_area());
        let (range, priced, plan) = if node.is_leaf() {
            let leaf = area * self.costs.leaf(node.prim_count);
            let range = (node.first_index, node.prim_count);
            (range, Priced::alone(leaf), Plan::LEAF)
        } else {
            let first = node.first_index as usize;
            let ((left, left_priced), (right, right_priced)) = if depth < PARALLEL_RANGE_DEPTH {
                rayon::join(
                    || self.measure(first, depth + 1),
                    || self.measure(first + 1, depth + 1),
                )
            } else {
                (
                    self.measure(first, depth + 1),
                    self.measure(first + 1, depth + 1),
                )
            };
            debug_assert_eq!(left.0 + left.1, right.0, "subtree ranges not contiguous");
            let range = (left.0, left.1 + right.1);
            let (priced, plan) = self.plan(range.1, area, &left_priced, &right_priced);
            (range, priced, plan)
        };
        let packed = (u64::from(range.0) << 32) | u64::from(range.1);
        self.ranges[index].store(packed, Ordering::Relaxed);
        self.plans[index].store(plan.0, Ordering::Relaxed);
        (range, priced)
    }

    /// The cheapest ways to place an interior node of `prims` primitives and box
    /// area `area` in 1 to [`WIDTH`] of its parent's slots, given its children's:
    /// in one slot on its own (a leaf, or a wide node whose slots its children
    /// share), or by giving its slots to its children, recursively (the SAH-optimal
    /// collapse of Ylitie et al., "Efficient Incoherent Ray Traversal on GPUs
    /// Through Compressed Wide BVHs", 2017). Greedily opening the largest child
    /// instead left a third of the dragon's wide nodes with two children.
    fn plan(&self, prims: u32, area: f64, left: &Priced, right: &Priced) -> (Priced, Plan) {
        // `shared[j - 1]`: the least cost of both children in at most `j` slots, the
        // left one taking at most `left_share[j - 1]` of them. Beyond the slots they
        // can use (one per binary leaf), more change nothing.
        let useful = (left.useful + right.useful).min(WIDTH);
        let mut shared = [f64::INFINITY; WIDTH];
        let mut left_share = [1u8; WIDTH];
        for slots in 2..=useful {
            let fewest = slots.saturating_sub(right.useful).max(1);
            for k in fewest..=left.useful.min(slots - 1) {
                let cost = left.best[k - 1] + right.best[slots - k - 1];
                if cost < shared[slots - 1] {
                    shared[slots - 1] = cost;
                    left_share[slots - 1] = k as u8;
                }
            }
        }
        for slots in useful + 1..=WIDTH {
            shared[slots - 1] = shared[useful - 1];
            left_share[slots - 1] = left_share[useful - 1];
        }
        let wide = area * self.costs.node + shared[WIDTH - 1];
        let leaf = if prims <= self.max_leaf_prims {
            area * self.costs.leaf(prims)
        } else {
            f64::INFINITY
        };
        // Only a leaf's cost can be infinite here; it never wins against a wide node
        // whose cost is infinite too.
        let is_leaf = leaf < wide;
        let mut priced = Priced::alone(if is_leaf { leaf } else { wide });
        priced.useful = useful;
        let mut plan = Plan::new(is_leaf, left_share[WIDTH - 1]);
        for slots in 2..=WIDTH {
            if shared[slots - 1] < priced.best[0] {
                priced.best[slots - 1] = shared[slots - 1];
                plan.share(slots, left_share[slots - 1]);
            }
        }
        (priced, plan)
    }

    fn plan_of(&self, index: usize) -> Plan {
        Plan(self.plans[index].load(Ordering::Relaxed))
    }

    /// The slots subtree `index` takes given at most `slots` of them, as planned,
    /// appended to `out`.
    fn expand(&self, index: usize, slots: usize, out: &mut Slots) {
        let plan = self.plan_of(index);
        match plan.left_share(slots) {
            None => out.push(index, plan.is_leaf()),
            Some(k) => {
                let first = self.nodes[index].first_index as usize;
                self.expand(first, k, out);
                self.expand(first + 1, slots - k, out);
            }
        }
    }

    fn range(&self, index: usize) -> (u32, u32) {
        let packed = self.ranges[index].load(Ordering::Relaxed);
        ((packed >> 32) as u32, packed as u32)
    }

    fn becomes_leaf(&self, index: usize) -> bool {
        self.plan_of(index).is_leaf()
    }

    /// Fills `node` from interior binary node `index` as planned: its two children
    /// share the eight slots (each in one slot, or opened into its own children's
    /// shares, and so on down). Leaf slots get their primitive range; the interior
    /// ones get `next_index` onwards in slot order, and are returned (binary node,
    /// wide index) in that order.
    fn fill(
        &self,
        index: usize,
        node: &mut WideNode,
        next_index: usize,
        interior: &mut Vec<(usize, usize)>,
    ) {
        let mut slots = Slots::default();
        let first = self.nodes[index].first_index as usize;
        let left_share = self.plan_of(index).wide_left_share();
        self.expand(first, left_share, &mut slots);
        self.expand(first + 1, WIDTH - left_share, &mut slots);
        interior.clear();
        for (slot, &(child, leaf)) in slots.taken().iter().enumerate() {
            node.set_child_bounds(slot, self.nodes[child].bounds());
            if leaf {
                let (first, count) = self.range(child);
                node.set_leaf(slot, first, count);
            } else {
                let wide_index = next_index + interior.len();
                node.set_node(slot, wide_index as u32);
                interior.push((child, wide_index));
            }
        }
    }

    /// The sequential walk from interior binary node `root`: its wide node first,
    /// then its descendants in walk order, child indices counted from the first.
    fn collapse_from(&self, root: usize) -> Vec<WideNode> {
        // Room for the usual number of nodes (the dragon has a wide node per 19
        // primitives), so that the array seldom grows and copies itself.
        let usual = self.range(root).1 as usize / 16 + 1;
        let mut nodes = Vec::with_capacity(usual);
        nodes.push(WideNode::EMPTY);
        let mut pending = vec![(root, 0usize)];
        let mut interior = Vec::with_capacity(WIDTH);
        while let Some((index, wide_index)) = pending.pop() {
            let next = nodes.len();
            self.fill(index, &mut nodes[wide_index], next, &mut interior);
            nodes.resize(next + interior.len(), WideNode::EMPTY);
            pending.extend_from_slice(&interior);
        }
        nodes
    }
}

/// What the plan weighs per unit of box area, in the binary builder's SAH units
/// ([`BvhParams`]): a ray's visit to a wide node, and its tests of a leaf.
#[derive(Clone, Copy, Debug)]
struct SlotCosts {
    node: f64,
    leaf_test: f64,
    /// Primitives one leaf test takes.
    block_size: u32,
}

impl SlotCosts {
    fn new(params: &BvhParams) -> SlotCosts {
        SlotCosts {
            node: f64::from(params.traversal_cost),
            leaf_test: f64::from(params.intersection_cost),
            block_size: params.block_size.max(1) as u32,
        }
    }

    fn leaf(&self, prims: u32) -> f64 {
        f64::from(prims.div_ceil(self.block_size)) * self.leaf_test
    }
}

/// A subtree's least cost in at most 1 to [`WIDTH`] of its parent's slots.
#[derive(Clone, Copy, Debug)]
struct Priced {
    /// `best[j - 1]`: in at most `j` slots.
    best: [f64; WIDTH],
    /// Slots beyond which `best` falls no further: the subtree's binary leaves (at
    /// most [`WIDTH`]).
    useful: usize,
}

impl Priced {
    /// A binary leaf, or any subtree in one slot.
    fn alone(cost: f64) -> Priced {
        Priced {
            best: [cost; WIDTH],
            useful: 1,
        }
    }
}

/// The children of one wide node as the plan gives them: `(binary node, is a leaf)`.
#[derive(Default)]
struct Slots {
    taken: [(usize, bool); WIDTH],
    len: usize,
}

impl Slots {
    fn push(&mut self, index: usize, leaf: bool) {
        self.taken[self.len] = (index, leaf);
        self.len += 1;
    }

    fn taken(&self) -> &[(usize, bool)] {
        &self.taken[..self.len]
    }
}

/// How a binary node's subtree takes its parent's slots, packed in a `u64`: byte 0
/// has bit 7 set if on its own it is a leaf (else a wide node) and, in its low
/// bits, how many of a wide node's [`WIDTH`] slots its left child gets; byte
/// `slots - 1` (for 2 to [`WIDTH`] slots) is 0 if with that many slots it still
/// takes one on its own, else how many of them its left child gets (its right
/// child takes the rest).
#[derive(Clone, Copy, Debug)]
struct Plan(u64);

impl Plan {
    const LEAF: Plan = Plan(0x80);

    fn new(is_leaf: bool, wide_left_share: u8) -> Plan {
        Plan(u64::from(wide_left_share) | if is_leaf { 0x80 } else { 0 })
    }

    fn share(&mut self, slots: usize, left_share: u8) {
        self.0 |= u64::from(left_share) << (8 * (slots - 1));
    }

    fn is_leaf(self) -> bool {
        self.0 & 0x80 != 0
    }

    fn wide_left_share(self) -> usize {
        (self.0 & 0x7f) as usize
    }

    fn left_share(self, slots: usize) -> Option<usize> {
        if slots < 2 {
            return None;
        }
        match (self.0 >> (8 * (slots - 1))) as u8 {
            0 => None,
            k => Some(usize::from(k)),
        }
    }
}

/// A wide node with the interior child indices renumbered by `renumber`.
fn renumbered(mut node: WideNode, renumber: impl Fn(u32) -> u32) -> WideNode {
    for slot in 0..WIDTH {
        // Interior children have an index above 0 (the root is nobody's child);
        // unused slots keep 0.
        if node.item_count[slot] == 0 && node.link[slot] != 0 {
            node.set_node(slot, renumber(node.link[slot]));
        }
    }
    node
}

/// One step of the top walk, in walk order.
enum Step {
    /// Top nodes `first..first + count` (indices among the top nodes) allocated.
    Nodes { first: usize, count: usize },
    /// Task `k`'s descendants come here.
    Task(usize),
}

impl WideBvh {
    /// Collapses `bvh` into the wide BVH of least SAH cost (`params`' costs, a wide
    /// node's visit priced as a binary node's) that keeps the binary tree's boxes:
    /// every wide node's children are binary nodes below it, and every binary leaf
    /// ends up in one wide leaf. So does a binary subtree of at most `max_leaf_prims`
    /// primitives where that is cheaper. A wide leaf at first refers to its
    /// primitive range (leaf order) as its items; the caller then makes its own items
    /// per leaf and points the leaves at them with [`WideBvh::assign_leaf_items`]. On
    /// all threads for big trees; the result does not depend on their number.
    pub fn collapse(bvh: &Bvh, max_leaf_prims: u32, params: &BvhParams) -> WideBvh {
        // A tree of `m` primitives has up to `2m - 1` nodes, most trees about `m`.
        let size = u32::try_from(bvh.nodes.len()).unwrap_or(u32::MAX);
        if size < PARALLEL_NODES {
            return WideBvh::collapse_sequential(bvh, max_leaf_prims, params);
        }
        let task_prims = TASK_PRIMS.min(size / 2 / MIN_TASKS);
        WideBvh::collapse_in_tasks(bvh, max_leaf_prims, params, task_prims)
    }

    /// [`WideBvh::collapse`] on one thread.
    pub fn collapse_sequential(bvh: &Bvh, max_leaf_prims: u32, params: &BvhParams) -> WideBvh {
        WideBvh::collapse_in_tasks(bvh, max_leaf_prims, params, u32::MAX)
    }

    /// [`WideBvh::collapse`], leaving binary subtrees of at most `task_prims`
    /// primitives to parallel tasks (`u32::MAX`: the whole tree is one task, done on
    /// this thread).
    pub(super) fn collapse_in_tasks(
        bvh: &Bvh,
        max_leaf_prims: u32,
        params: &BvhParams,
        task_prims: u32,
    ) -> WideBvh {
        let Some(root) = bvh.nodes.first() else {
            return WideBvh::default();
        };
        let sequential = task_prims == u32::MAX;
        let binary = Binary::new(bvh, max_leaf_prims, SlotCosts::new(params), !sequential);
        if binary.becomes_leaf(0) {
            let mut node = WideNode::EMPTY;
            let (first, count) = binary.range(0);
            node.set_leaf(0, first, count);
            node.set_child_bounds(0, root.bounds());
            return WideBvh { nodes: vec![node] };
        }
        if sequential {
            return WideBvh {
                nodes: binary.collapse_from(0),
            };
        }

        // The top walk: as the sequential one, but a subtree small enough becomes a
        // task, and its descendants a gap in the walk order.
        let mut top = vec![WideNode::EMPTY];
        // (binary node, top index of its wide node)
        let mut tasks: Vec<(usize, usize)> = Vec::new();
        let mut steps = Vec::new();
        let mut pending = vec![(0usize, 0usize)];
        let mut interior = Vec::with_capacity(WIDTH);
        while let Some((index, wide_index)) = pending.pop() {
            if binary.range(index).1 <= task_prims {
                steps.push(Step::Task(tasks.len()));
                tasks.push((index, wide_index));
                continue;
            }
            let next = top.len();
            binary.fill(index, &mut top[wide_index], next, &mut interior);
            top.resize(next + interior.len(), WideNode::EMPTY);
            steps.push(Step::Nodes {
                first: next,
                count: interior.len(),
            });
            pending.extend_from_slice(&interior);
        }
        let collapsed: Vec<Vec<WideNode>> = tasks
            .par_iter()
            .map(|&(index, _)| binary.collapse_from(index))
            .collect();

        // Final indices: the top nodes' and the start of each task's descendants.
        let mut final_index = vec![0u32; top.len()];
        let mut task_start = vec![0u32; tasks.len()];
        let mut next = 1u32;
        for step in &steps {
            match *step {
                Step::Nodes { first, count } => {
                    for (k, index) in final_index[first..first + count].iter_mut().enumerate() {
                        *index = next + k as u32;
                    }
                    next += count as u32;
                }
                Step::Task(k) => {
                    task_start[k] = next;
                    next += collapsed[k].len() as u32 - 1;
                }
            }
        }
        let total = next as usize;

        // A task's node `i > 0` goes to its start plus `i - 1`, its node 0 to the top
        // node it fills.
        let mut nodes: Vec<WideNode> = Vec::with_capacity(total);
        let out = &mut nodes.spare_capacity_mut()[..total];
        let mut filled_by_task = vec![None; top.len()];
        for (k, &(_, wide_index)) in tasks.iter().enumerate() {
            filled_by_task[wide_index] = Some(k);
        }
        for (top_index, node) in top.iter().enumerate() {
            let node = match filled_by_task[top_index] {
                Some(k) => renumbered(collapsed[k][0], |i| task_start[k] + i - 1),
                None => renumbered(*node, |i| final_index[i as usize]),
            };
            out[final_index[top_index] as usize].write(node);
        }
        // Cut the tasks' runs out of the array, in walk order, and fill them.
        let mut runs = Vec::with_capacity(tasks.len());
        let mut rest = out;
        let mut at = 0;
        for (k, &start) in task_start.iter().enumerate() {
            let len = collapsed[k].len() - 1;
            let (_, tail) = std::mem::take(&mut rest).split_at_mut(start as usize - at);
            let (run, tail) = tail.split_at_mut(len);
            runs.push((k, run));
            rest = tail;
            at = start as usize + len;
        }
        runs.into_par_iter().for_each(|(k, run)| {
            let start = task_start[k];
            for (slot, &node) in run.iter_mut().zip(&collapsed[k][1..]) {
                slot.write(renumbered(node, |i| start + i - 1));
            }
        });
        // SAFETY: the top nodes and the tasks' runs are written above; together
        // they are every index below `total` (the walk allocates each once).
        unsafe { nodes.set_len(total) };
        WideBvh { nodes }
    }
}

#[cfg(test)]
mod tests {
    use rand::{Rng, SeedableRng};

    use super::*;
    use crate::math::{Aabb, Vec3};

    /// A collapse that fills each wide node by opening, one after another, the slot
    /// `open` picks among the slots given (`(binary node, whether it may become a
    /// leaf)`), until it picks none or eight slots are used; a slot left that may
    /// become a leaf does. Any such collapse is one the plan weighs.
    fn collapse_by(
        bvh: &Bvh,
        max_leaf_prims: u32,
        mut open: impl FnMut(&[(usize, bool)]) -> Option<usize>,
    ) -> WideBvh {
        let binary = &bvh.nodes;
        let Some(root) = binary.first() else {
            return WideBvh::default();
        };
        let mut ranges = vec![(0u32, 0u32); binary.len()];
        for index in (0..binary.len()).rev() {
            let node = &binary[index];
            ranges[index] = if node.is_leaf() {
                (node.first_index, node.prim_count)
            } else {
                let first = node.first_index as usize;
                (ranges[first].0, ranges[first].1 + ranges[first + 1].1)
            };
        }
        let may_be_leaf =
            |index: usize| binary[index].is_leaf() || ranges[index].1 <= max_leaf_prims;
        let mut nodes = vec![WideNode::EMPTY];
        if binary[0].is_leaf() {
            nodes[0].set_leaf(0, ranges[0].0, ranges[0].1);
            nodes[0].set_child_bounds(0, root.bounds());
            return WideBvh { nodes };
        }
        let mut pending = vec![(0usize, 0usize)];
        while let Some((binary_index, wide_index)) = pending.pop() {
            let first = binary[binary_index].first_index as usize;
            let mut slots: Vec<(usize, bool)> = vec![
                (first, may_be_leaf(first)),
                (first + 1, may_be_leaf(first + 1)),
            ];
            while slots.len() < WIDTH {
                let Some(position) = open(&slots) else {
                    break;
                };
                let (opened, _) = slots.swap_remove(position);
                assert!(!binary[opened].is_leaf(), "a binary leaf cannot be opened");
                let first = binary[opened].first_index as usize;
                slots.extend([
                    (first, may_be_leaf(first)),
                    (first + 1, may_be_leaf(first + 1)),
                ]);
            }
            for (slot, &(child, leaf)) in slots.iter().enumerate() {
                nodes[wide_index].set_child_bounds(slot, binary[child].bounds());
                if leaf {
                    nodes[wide_index].set_leaf(slot, ranges[child].0, ranges[child].1);
                } else {
                    let next = nodes.len() as u32;
                    nodes[wide_index].set_node(slot, next);
                    pending.push((child, nodes.len()));
                    nodes.push(WideNode::EMPTY);
                }
            }
        }
        WideBvh { nodes }
    }

    /// The collapse before the plan: open the largest slot that is not a leaf.
    fn collapse_greedy(bvh: &Bvh, max_leaf_prims: u32) -> WideBvh {
        let area = |index: usize| bvh.nodes[index].bounds().half_area();
        collapse_by(bvh, max_leaf_prims, |slots| {
            (0..slots.len())
                .filter(|&position| !slots[position].1)
                .max_by(|&a, &b| area(slots[a].0).total_cmp(&area(slots[b].0)))
        })
    }

    /// Boxes of random sizes, in clusters, so that the tree has subtrees of many
    /// sizes.
    fn boxes(count: usize, seed: u64) -> Vec<Aabb> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let centres: Vec<Vec3> = (0..7)
            .map(|_| Vec3::new(rng.random(), rng.random(), rng.random()) * 100.0)
            .collect();
        (0..count)
            .map(|_| {
                let centre = centres[rng.random_range(0..centres.len())];
                let min = centre
                    + Vec3::new(
                        rng.random_range(-10.0..10.0),
                        rng.random_range(-10.0..10.0),
                        rng.random_range(-10.0..10.0),
                    );
                let size = Vec3::new(rng.random(), rng.random(), rng.random())
                    * rng.random_range(0.01..3.0);
                Aabb {
                    min,
                    max: min + size,
                }
            })
            .collect()
    }

    /// Binary trees with leaves of up to `max_leaf_size` primitives, so that with
    /// `max_leaf_prims` above it some interior subtrees may become leaves too.
    fn params(max_leaf_size: usize) -> BvhParams {
        BvhParams {
            min_leaf_size: 1,
            max_leaf_size,
            ..BvhParams::default()
        }
    }

    fn same(a: &WideBvh, b: &WideBvh) -> bool {
        a.nodes.len() == b.nodes.len()
            && a.nodes.iter().zip(&b.nodes).all(|(a, b)| {
                a.link == b.link
                    && a.item_count == b.item_count
                    && (0..WIDTH).all(|s| a.child_bounds(s) == b.child_bounds(s))
            })
    }

    fn cost(wide: &WideBvh, params: &BvhParams) -> f64 {
        wide.sah_cost(params, |prims| params.leaf_tests(prims as usize))
    }

    /// The parallel collapse makes exactly the nodes of the sequential walk, in the
    /// same order, whatever the size of its tasks.
    #[test]
    fn parallel_collapse_equals_the_sequential_one() {
        for (count, seed) in [(2, 1), (9, 2), (100, 3), (3000, 4), (20_000, 5)] {
            for (params, max_leaf_prims) in [
                (BvhParams::default(), 8),
                (params(1), 1),
                (params(2), 4),
                (params(4), 8),
            ] {
                let (bvh, _) = Bvh::build(&boxes(count, seed), &params);
                let sequential = WideBvh::collapse_sequential(&bvh, max_leaf_prims, &params);
                for task_prims in [1, 2, 7, 50, 1000, 5000] {
                    let parallel =
                        WideBvh::collapse_in_tasks(&bvh, max_leaf_prims, &params, task_prims);
                    assert!(
                        same(&parallel, &sequential),
                        "{count} boxes, leaves of {max_leaf_prims}, tasks of {task_prims}"
                    );
                }
                assert!(same(
                    &WideBvh::collapse(&bvh, max_leaf_prims, &params),
                    &sequential
                ));
            }
        }
    }

    /// No collapse of the same binary tree costs less than the planned one: neither
    /// the greedy one it replaced (which it beats by a margin on larger trees, with
    /// fewer nodes) nor any of many random ones.
    #[test]
    fn the_planned_collapse_is_the_cheapest() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        for (count, seed) in [(9, 2), (40, 8), (100, 3), (3000, 4), (20_000, 5)] {
            for (params, max_leaf_prims) in
                [(BvhParams::default(), 8), (params(1), 1), (params(2), 4)]
            {
                let (bvh, order) = Bvh::build(&boxes(count, seed), &params);
                let planned = WideBvh::collapse(&bvh, max_leaf_prims, &params);
                let all = boxes(count, seed);
                let leaf_order: Vec<Aabb> = order.iter().map(|&i| all[i as usize]).collect();
                planned
                    .validate(count, |prim| leaf_order[prim as usize])
                    .unwrap();
                let planned_cost = cost(&planned, &params);
                // Relative slack for the sums' rounding.
                let at_least = |other: f64| planned_cost <= other * (1.0 + 1e-9);
                let greedy = collapse_greedy(&bvh, max_leaf_prims);
                let greedy_cost = cost(&greedy, &params);
                assert!(
                    at_least(greedy_cost),
                    "{count} boxes: planned {planned_cost}, greedy {greedy_cost}"
                );
                if count >= 3000 {
                    assert!(planned_cost < greedy_cost * 0.999, "{count} boxes");
                    assert!(planned.nodes.len() < greedy.nodes.len(), "{count} boxes");
                }
                let tries = if count <= 100 { 200 } else { 5 };
                for _ in 0..tries {
                    let random = collapse_by(&bvh, max_leaf_prims, |slots| {
                        let openable: Vec<usize> = (0..slots.len())
                            .filter(|&p| !bvh.nodes[slots[p].0].is_leaf())
                            .collect();
                        if openable.is_empty() || rng.random_bool(0.2) {
                            return None;
                        }
                        Some(openable[rng.random_range(0..openable.len())])
                    });
                    let random_cost = cost(&random, &params);
                    assert!(
                        at_least(random_cost),
                        "{count} boxes: planned {planned_cost}, random {random_cost}"
                    );
                }
            }
        }
    }
}
