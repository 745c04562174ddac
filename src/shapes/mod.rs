//! Intersection kernels for the two primitive kinds.
//!
//! Kernels return only the distance and the barycentric/parametric coordinates of a
//! hit ([`PrimHit`]); points, normals and materials are rebuilt once, for the closest
//! hit, by the scene (two-phase hits, as pbrt's `TriangleIntersection`).

mod across;
mod lanes;
mod packet;
mod sphere;
mod triangle;

pub use across::{sphere_across_rays, triangle_across_rays};
pub use packet::{LANES, MAX_PRIM, PacketRay, TrianglePacket};
pub use sphere::Sphere;
pub use triangle::Triangle;

use crate::math::{Aabb, Float, Ray};

/// Where a ray meets one primitive: distance along the ray and the barycentric
/// coordinates of the hit (`u`, `v` weight vertices 1 and 2; zero for spheres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PrimHit {
    /// Distance along the (unit-direction) ray.
    pub t: Float,
    /// Barycentric weight of vertex 1.
    pub u: Float,
    /// Barycentric weight of vertex 2.
    pub v: Float,
}

/// A primitive as the intersection loop sees it: a closed set, so an enum matched in
/// the loop rather than a trait object.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// A triangle stored for intersection.
    Triangle(Triangle),
    /// A sphere.
    Sphere(Sphere),
}

impl Shape {
    /// The nearest hit with `0 < t < t_max`, if any.
    #[inline(always)]
    pub fn intersect(&self, ray: &Ray, t_max: Float) -> Option<PrimHit> {
        match self {
            Shape::Triangle(tri) => tri.intersect(ray, t_max),
            Shape::Sphere(s) => s.intersect(ray, t_max),
        }
    }

    /// The bounding box.
    pub fn bounds(&self) -> Aabb {
        match self {
            Shape::Triangle(tri) => tri.bounds(),
            Shape::Sphere(s) => s.bounds(),
        }
    }
}
