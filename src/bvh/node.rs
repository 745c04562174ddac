use crate::math::{Aabb, Vec3};

/// One BVH node in 32 bytes, the layout of tinybvh's `BVHNode` and pbrt's
/// `LinearBVHNode`: two cache-friendly halves of box corner plus index.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(32))]
pub struct BvhNode {
    /// Lower corner of the box around everything below this node.
    pub min: [f32; 3],
    /// Leaf: index of the first primitive (in leaf order). Interior: index of the
    /// first child; the second child is at `first_index + 1`.
    pub first_index: u32,
    /// Upper corner of the box.
    pub max: [f32; 3],
    /// Leaf: number of primitives, at least 1. Interior: 0.
    pub prim_count: u32,
}

const _: () = assert!(std::mem::size_of::<BvhNode>() == 32);

impl BvhNode {
    /// Whether this node holds primitives rather than children.
    #[inline(always)]
    pub fn is_leaf(&self) -> bool {
        self.prim_count > 0
    }

    /// The node's box.
    #[inline]
    pub fn bounds(&self) -> Aabb {
        Aabb {
            min: Vec3::from(self.min),
            max: Vec3::from(self.max),
        }
    }

    pub(crate) fn set_bounds(&mut self, b: Aabb) {
        self.min = b.min.into();
        self.max = b.max.into();
    }
}
