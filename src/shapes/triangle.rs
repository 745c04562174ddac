use super::PrimHit;
use crate::math::{Aabb, Float, Ray, Vec3};

/// How far outside the edges (in barycentric units) a hit still counts. Möller–Trumbore
/// is not watertight: without this slack a ray through a shared edge can slip between
/// the two triangles in `f32`. Widening every triangle by ~1e-6 of its size closes such
/// cracks; a double hit on an edge is harmless.
pub(crate) const EDGE_SLACK: Float = 1e-6;

/// A triangle stored for the Möller–Trumbore kernel: one vertex and two edges.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    /// Vertex 0.
    pub v0: Vec3,
    /// `v1 - v0`.
    pub e1: Vec3,
    /// `v2 - v0`.
    pub e2: Vec3,
}

impl Triangle {
    /// The triangle with vertices `p0`, `p1`, `p2`.
    pub fn new(p0: Vec3, p1: Vec3, p2: Vec3) -> Triangle {
        Triangle {
            v0: p0,
            e1: p1 - p0,
            e2: p2 - p0,
        }
    }

    /// The three vertices.
    pub fn vertices(&self) -> [Vec3; 3] {
        [self.v0, self.v0 + self.e1, self.v0 + self.e2]
    }

    /// The unnormalized geometric normal `e1 x e2` (counter-clockwise winding).
    #[inline]
    pub fn normal(&self) -> Vec3 {
        self.e1.cross(self.e2)
    }

    /// Whether the triangle has no normal to shade or intersect with: zero area
    /// (repeated or collinear corners, or corners so close that `e1 x e2` underflows
    /// to zero) or a normal beyond `f32` (corners near 1e38). The one rule by which
    /// the scene drops triangles and `raytracer info` counts them. A normal too small
    /// for its squared length is not degenerate: [`try_unit`](crate::math::try_unit)
    /// still finds its direction, and the kernel still hits the triangle.
    #[inline]
    pub fn is_degenerate(&self) -> bool {
        let n = self.normal();
        !(n.is_finite() && n != Vec3::ZERO)
    }

    /// The bounding box.
    pub fn bounds(&self) -> Aabb {
        Aabb::from_points(&self.vertices())
    }

    /// The nearest hit with `0 < t < t_max`, by Möller–Trumbore
    /// (Möller and Trumbore, "Fast, Minimum Storage Ray/Triangle Intersection", 1997).
    /// A ray parallel to the plane (zero determinant) misses.
    #[inline(always)]
    pub fn intersect(&self, ray: &Ray, t_max: Float) -> Option<PrimHit> {
        let p = ray.dir.cross(self.e2);
        let det = self.e1.dot(p);
        if det == 0.0 {
            return None;
        }
        let inv_det = 1.0 / det;
        let s = ray.origin - self.v0;
        let u = s.dot(p) * inv_det;
        if !(-EDGE_SLACK..=1.0 + EDGE_SLACK).contains(&u) {
            return None;
        }
        let q = s.cross(self.e1);
        let v = ray.dir.dot(q) * inv_det;
        if v < -EDGE_SLACK || u + v > 1.0 + EDGE_SLACK {
            return None;
        }
        let t = self.e2.dot(q) * inv_det;
        (t > 0.0 && t < t_max).then_some(PrimHit { t, u, v })
    }
}
