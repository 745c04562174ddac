//! Collapsing the binary BVH into the 8-wide one, on all threads, into exactly the
//! tree and node order of the sequential walk.
//!
//! The sequential walk (kept as [`WideBvh::collapse_sequential`], the reference of
//! the tests) fills the wide node of binary node `b` by opening the largest interior
//! child until eight slots are used, gives the node's interior children the next
//! indices in slot order, and goes on from a stack, last child first. So the
//! descendants of a wide node take one contiguous run of indices, allocated after
//! its own. The parallel collapse walks the top of the tree the same way but leaves
//! every binary subtree of at most `task_prims` primitives to a task, which collapses
//! it on its own into a local array of its nodes in sequential order; a task's run of
//! indices is known once the tasks before it in walk order know their sizes, and one
//! parallel copy puts every node in its place.

use std::sync::atomic::{AtomicU64, Ordering};

use rayon::prelude::*;

use super::wide::{WIDTH, WideBvh, WideNode};
use super::{Bvh, BvhNode};

/// Binary subtrees of at most this many primitives are collapsed as one task (or
/// more, for small trees: at least [`MIN_TASKS`] of them).
const TASK_PRIMS: u32 = 16 * 1024;

/// Tasks enough for both threads to stay busy to the end.
const MIN_TASKS: u32 = 64;

/// Trees of fewer binary nodes are collapsed sequentially.
const PARALLEL_NODES: u32 = 8 * 1024;

/// Depth of the binary tree to which the subtree ranges are measured in parallel.
const PARALLEL_RANGE_DEPTH: usize = 8;

/// The binary tree with every node's primitive range, and the collapse rules.
struct Binary<'a> {
    nodes: &'a [BvhNode],
    /// `(first primitive, count)` of every node's subtree, packed as
    /// `first << 32 | count`.
    ranges: Vec<AtomicU64>,
    max_leaf_prims: u32,
}

impl<'a> Binary<'a> {
    /// Measures every subtree's primitive range (the builder partitions primitives in
    /// place, so each subtree's are contiguous), the top levels on all threads.
    fn new(bvh: &'a Bvh, max_leaf_prims: u32, parallel: bool) -> Binary<'a> {
        let nodes = &bvh.nodes[..];
        let binary = Binary {
            nodes,
            ranges: (0..nodes.len())
                .into_par_iter()
                .map(|_| AtomicU64::new(0))
                .collect(),
            max_leaf_prims,
        };
        let depth = if parallel { 0 } else { PARALLEL_RANGE_DEPTH };
        binary.measure(0, depth);
        binary
    }

    fn measure(&self, index: usize, depth: usize) -> (u32, u32) {
        let node = &self.nodes[index];
        let range = if node.is_leaf() {
            (node.first_index, node.prim_count)
        } else {
            let first = node.first_index as usize;
            let (left, right) = if depth < PARALLEL_RANGE_DEPTH {
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
            (left.0, left.1 + right.1)
        };
        let packed = (u64::from(range.0) << 32) | u64::from(range.1);
        self.ranges[index].store(packed, Ordering::Relaxed);
        range
    }

    fn range(&self, index: usize) -> (u32, u32) {
        let packed = self.ranges[index].load(Ordering::Relaxed);
        ((packed >> 32) as u32, packed as u32)
    }

    fn becomes_leaf(&self, index: usize) -> bool {
        self.nodes[index].is_leaf() || self.range(index).1 <= self.max_leaf_prims
    }

    /// Fills `node` from interior binary node `index`: opens it, then keeps opening
    /// the largest opened child that is still interior until eight slots are used.
    /// Leaf slots get their primitive range; the interior ones get `next_index`
    /// onwards in slot order, and are returned (binary node, wide index) in that
    /// order.
    fn fill(
        &self,
        index: usize,
        node: &mut WideNode,
        next_index: usize,
        interior: &mut Vec<(usize, usize)>,
    ) {
        let area = |index: usize| self.nodes[index].bounds().half_area();
        let first = self.nodes[index].first_index as usize;
        let mut slots = [0usize; WIDTH];
        slots[..2].copy_from_slice(&[first, first + 1]);
        let mut used = 2;
        while used < WIDTH {
            let widest = (0..used)
                .filter(|&position| !self.becomes_leaf(slots[position]))
                .max_by(|&a, &b| area(slots[a]).total_cmp(&area(slots[b])));
            let Some(position) = widest else {
                break;
            };
            // As `Vec::swap_remove` then two pushes.
            let opened = slots[position];
            slots[position] = slots[used - 1];
            let first = self.nodes[opened].first_index as usize;
            slots[used - 1] = first;
            slots[used] = first + 1;
            used += 1;
        }
        interior.clear();
        for (slot, &child) in slots[..used].iter().enumerate() {
            node.set_child_bounds(slot, self.nodes[child].bounds());
            if self.becomes_leaf(child) {
                (node.child[slot], node.item_count[slot]) = self.range(child);
            } else {
                let wide_index = next_index + interior.len();
                node.child[slot] = wide_index as u32;
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

/// A wide node with the interior child indices renumbered by `renumber`.
fn renumbered(mut node: WideNode, renumber: impl Fn(u32) -> u32) -> WideNode {
    for slot in 0..WIDTH {
        // Interior children have an index above 0 (the root is nobody's child);
        // unused slots keep 0.
        if node.item_count[slot] == 0 && node.child[slot] != 0 {
            node.child[slot] = renumber(node.child[slot]);
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
    /// Collapses `bvh` into a wide BVH. Every binary subtree of at most
    /// `max_leaf_prims` primitives, and every binary leaf, becomes one wide leaf,
    /// which at first refers to its primitive range (leaf order) as its items; the
    /// caller then makes its own items per leaf and points the leaves at them with
    /// [`WideBvh::assign_leaf_items`]. On all threads for big trees; the result does
    /// not depend on their number.
    pub fn collapse(bvh: &Bvh, max_leaf_prims: u32) -> WideBvh {
        // A tree of `m` primitives has up to `2m - 1` nodes, most trees about `m`.
        let size = u32::try_from(bvh.nodes.len()).unwrap_or(u32::MAX);
        if size < PARALLEL_NODES {
            return WideBvh::collapse_sequential(bvh, max_leaf_prims);
        }
        let task_prims = TASK_PRIMS.min(size / 2 / MIN_TASKS);
        WideBvh::collapse_in_tasks(bvh, max_leaf_prims, task_prims)
    }

    /// [`WideBvh::collapse`] on one thread.
    pub fn collapse_sequential(bvh: &Bvh, max_leaf_prims: u32) -> WideBvh {
        WideBvh::collapse_in_tasks(bvh, max_leaf_prims, u32::MAX)
    }

    /// [`WideBvh::collapse`], leaving binary subtrees of at most `task_prims`
    /// primitives to parallel tasks (`u32::MAX`: the whole tree is one task, done on
    /// this thread).
    pub(super) fn collapse_in_tasks(bvh: &Bvh, max_leaf_prims: u32, task_prims: u32) -> WideBvh {
        let Some(root) = bvh.nodes.first() else {
            return WideBvh::default();
        };
        let sequential = task_prims == u32::MAX;
        let binary = Binary::new(bvh, max_leaf_prims, !sequential);
        if binary.becomes_leaf(0) {
            let mut node = WideNode::EMPTY;
            (node.child[0], node.item_count[0]) = binary.range(0);
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
    use crate::bvh::BvhParams;
    use crate::math::{Aabb, Vec3};

    /// The collapse as it was before it ran in parallel, word for word: the
    /// reference both collapses must equal.
    fn collapse_before(bvh: &Bvh, max_leaf_prims: u32) -> WideBvh {
        let binary = &bvh.nodes;
        let Some(root) = binary.first() else {
            return WideBvh::default();
        };
        // Primitive range of every binary subtree. The builder appends children after
        // their parent and partitions primitives in place, so a backwards sweep sees
        // children first and every subtree's primitives are contiguous.
        let mut ranges = vec![(0u32, 0u32); binary.len()];
        for index in (0..binary.len()).rev() {
            let node = &binary[index];
            ranges[index] = if node.is_leaf() {
                (node.first_index, node.prim_count)
            } else {
                let first = node.first_index as usize;
                let (left, right) = (ranges[first], ranges[first + 1]);
                debug_assert_eq!(left.0 + left.1, right.0, "subtree ranges not contiguous");
                (left.0, left.1 + right.1)
            };
        }
        let becomes_leaf =
            |index: usize| binary[index].is_leaf() || ranges[index].1 <= max_leaf_prims;
        let area = |index: usize| binary[index].bounds().half_area();

        let mut nodes = Vec::with_capacity(binary.len() / (2 * WIDTH));
        nodes.push(WideNode::EMPTY);
        if becomes_leaf(0) {
            (nodes[0].child[0], nodes[0].item_count[0]) = ranges[0];
            nodes[0].set_child_bounds(0, root.bounds());
            return WideBvh { nodes };
        }
        // (binary interior node, wide node to fill from it)
        let mut pending = vec![(0usize, 0usize)];
        let mut slots: Vec<usize> = Vec::with_capacity(WIDTH);
        while let Some((binary_index, wide_index)) = pending.pop() {
            // Open the binary node, then keep opening the largest opened child that
            // is still interior until eight slots are used.
            let first = binary[binary_index].first_index as usize;
            slots.clear();
            slots.extend([first, first + 1]);
            while slots.len() < WIDTH {
                let widest = (0..slots.len())
                    .filter(|&position| !becomes_leaf(slots[position]))
                    .max_by(|&a, &b| area(slots[a]).total_cmp(&area(slots[b])));
                let Some(position) = widest else {
                    break;
                };
                let opened = slots.swap_remove(position);
                let first = binary[opened].first_index as usize;
                slots.extend([first, first + 1]);
            }
            for (slot, &child) in slots.iter().enumerate() {
                nodes[wide_index].set_child_bounds(slot, binary[child].bounds());
                if becomes_leaf(child) {
                    (
                        nodes[wide_index].child[slot],
                        nodes[wide_index].item_count[slot],
                    ) = ranges[child];
                } else {
                    nodes[wide_index].child[slot] = nodes.len() as u32;
                    pending.push((child, nodes.len()));
                    nodes.push(WideNode::EMPTY);
                }
            }
        }
        WideBvh { nodes }
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

    /// The parallel collapse makes exactly the nodes the sequential walk made before
    /// it, in the same order, whatever the size of its tasks.
    #[test]
    fn parallel_collapse_equals_the_sequential_one() {
        for (count, seed) in [(2, 1), (9, 2), (100, 3), (3000, 4), (20_000, 5)] {
            let (bvh, _) = Bvh::build(&boxes(count, seed), &BvhParams::default());
            for max_leaf_prims in [1, 4, 8] {
                let sequential = collapse_before(&bvh, max_leaf_prims);
                let same = |wide: &WideBvh| {
                    wide.nodes.len() == sequential.nodes.len()
                        && wide.nodes.iter().zip(&sequential.nodes).all(|(a, b)| {
                            a.child == b.child
                                && a.item_count == b.item_count
                                && (0..WIDTH).all(|s| a.child_bounds(s) == b.child_bounds(s))
                        })
                };
                for task_prims in [1, 2, 7, 50, 1000, 5000] {
                    let parallel = WideBvh::collapse_in_tasks(&bvh, max_leaf_prims, task_prims);
                    assert!(
                        same(&parallel),
                        "{count} boxes, leaves of {max_leaf_prims}, tasks of {task_prims}"
                    );
                }
                assert!(same(&WideBvh::collapse(&bvh, max_leaf_prims)));
                assert!(same(&WideBvh::collapse_sequential(&bvh, max_leaf_prims)));
            }
        }
    }
}
