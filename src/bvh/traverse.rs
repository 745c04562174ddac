//! Iterative traversal with a fixed stack, nearest child first.

use super::{Bvh, BvhNode, MAX_DEPTH};
use glam::{BVec4A, Vec4};

use crate::math::{Float, Ray, Vec3};

/// Slack on the exit distance of the slab test so that rounding in `(min - o) / d`
/// never culls a box the ray grazes: pbrt's `1 + 2 * gamma(3)`.
const SLAB_EXIT_SLACK: Float = 1.0 + 2.0 * 3.0 * (Float::EPSILON * 0.5);

/// Smallest direction component the slab test divides by. A zero component would
/// give an infinite reciprocal and `0 * inf = NaN` for a ray lying in a slab's plane;
/// with this floor the product is 0 and such a ray counts as inside the (closed) box,
/// as it should (obvhs's `safe_inverse` does the same).
const MIN_DIR_COMPONENT: Float = 1e-30;

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
    /// Prepares `ray` for traversal.
    #[inline]
    pub fn new(ray: &Ray) -> RayQuery {
        let safe = |d: Float| {
            if d.abs() < MIN_DIR_COMPONENT {
                MIN_DIR_COMPONENT.copysign(d)
            } else {
                d
            }
        };
        let inv_dir = Vec3::new(safe(ray.dir.x), safe(ray.dir.y), safe(ray.dir.z)).recip();
        debug_assert!(inv_dir.is_finite());
        RayQuery {
            origin: ray.origin.extend(0.0),
            inv_dir: inv_dir.extend(0.0),
        }
    }

    /// Entry distance into `node`'s box if the ray meets it within `[0, t_max)`,
    /// otherwise `Float::INFINITY`. A ray starting inside the box enters at 0.
    ///
    /// The six slab distances are computed four lanes at a time; the node's index
    /// words sit in the fourth lanes and are masked to zero first, since as floats
    /// they would be denormals, which cost a microcode assist in arithmetic.
    #[inline(always)]
    fn entry(&self, node: &BvhNode, t_max: Float) -> Float {
        let min = Vec4::select(XYZ, node.min_lane(), Vec4::ZERO);
        let max = Vec4::select(XYZ, node.max_lane(), Vec4::ZERO);
        let t1 = (min - self.origin) * self.inv_dir;
        let t2 = (max - self.origin) * self.inv_dir;
        // The fourth lane is 0 in both: it clamps the entry at 0 for free, and the
        // exit at 0 would be wrong, so the exit takes only x, y, z.
        let t_enter = t1.min(t2).max_element();
        let far = t1.max(t2);
        let t_exit = far.x.min(far.y).min(far.z) * SLAB_EXIT_SLACK;
        if t_enter <= t_exit && t_enter < t_max {
            t_enter
        } else {
            Float::INFINITY
        }
    }
}

/// Keeps x, y, z and clears w.
const XYZ: BVec4A = BVec4A::from_array([true, true, true, false]);

impl Bvh {
    /// Finds the closest hit. `hit(prim, t_max)` intersects primitive `prim` (leaf
    /// order) and returns the hit distance if it is below `t_max`; the caller keeps
    /// whatever else it needs about that hit. Returns the closest distance found, or
    /// `t_max` if none.
    #[inline]
    pub fn intersect<F>(&self, ray: &RayQuery, mut t_max: Float, mut hit: F) -> Float
    where
        F: FnMut(u32, Float) -> Option<Float>,
    {
        self.walk(ray, &mut t_max, |first, count, t_max| {
            for prim in first..first + count {
                if let Some(t) = hit(prim, *t_max) {
                    *t_max = t;
                }
            }
            false
        });
        t_max
    }

    /// Whether any primitive blocks the ray before `t_max`. `blocks(prim, t_max)`
    /// intersects primitive `prim`; traversal stops at the first `true`.
    #[inline]
    pub fn occluded<F>(&self, ray: &RayQuery, mut t_max: Float, mut blocks: F) -> bool
    where
        F: FnMut(u32, Float) -> bool,
    {
        self.walk(ray, &mut t_max, |first, count, t_max| {
            (first..first + count).any(|prim| blocks(prim, *t_max))
        })
    }

    /// The shared loop: visits leaves front to back, calling `leaf(first, count,
    /// t_max)`, which may shrink `t_max` and returns `true` to stop. Returns whether a
    /// leaf stopped the walk.
    #[inline(always)]
    fn walk<F>(&self, ray: &RayQuery, t_max: &mut Float, mut leaf: F) -> bool
    where
        F: FnMut(u32, u32, &mut Float) -> bool,
    {
        let Some(root) = self.nodes.first() else {
            return false;
        };
        if ray.entry(root, *t_max) == Float::INFINITY {
            return false;
        }
        // Pending far children with their entry distances, skipped when a closer
        // hit has been found since they were pushed.
        let mut stack = [(0u32, 0.0 as Float); MAX_DEPTH];
        let mut stack_len = 0;
        let mut node = root;
        loop {
            if node.is_leaf() {
                if leaf(node.first_index, node.prim_count, t_max) {
                    return true;
                }
            } else {
                let first = node.first_index as usize;
                let (mut near, mut far) = (first, first + 1);
                let mut t_near = ray.entry(&self.nodes[near], *t_max);
                let mut t_far = ray.entry(&self.nodes[far], *t_max);
                if t_far < t_near {
                    std::mem::swap(&mut near, &mut far);
                    std::mem::swap(&mut t_near, &mut t_far);
                }
                if t_near != Float::INFINITY {
                    if t_far != Float::INFINITY {
                        stack[stack_len] = (far as u32, t_far);
                        stack_len += 1;
                    }
                    node = &self.nodes[near];
                    continue;
                }
            }
            // Pop the next pending node that can still hold a closer hit.
            loop {
                if stack_len == 0 {
                    return false;
                }
                stack_len -= 1;
                let (index, t_entry) = stack[stack_len];
                if t_entry < *t_max {
                    node = &self.nodes[index as usize];
                    break;
                }
            }
        }
    }
}
