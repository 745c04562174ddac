use super::PrimHit;
use crate::math::{Aabb, Float, Ray, Vec3};

/// A sphere.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    /// Centre.
    pub center: Vec3,
    /// Radius, positive.
    pub radius: Float,
}

impl Sphere {
    /// The bounding box.
    pub fn bounds(&self) -> Aabb {
        Aabb {
            min: self.center - Vec3::splat(self.radius),
            max: self.center + Vec3::splat(self.radius),
        }
    }

    /// The nearest hit with `0 < t < t_max`: the near root, or the far one when the ray
    /// starts inside.
    ///
    /// The discriminant is computed as `r^2 - |oc - b d|^2` rather than `b^2 - c`, which
    /// keeps its precision for rays that pass far from the centre (Haines et al.,
    /// "Precision Improvements for Ray/Sphere Intersection", Ray Tracing Gems, 2019).
    #[inline(always)]
    pub fn intersect(&self, ray: &Ray, t_max: Float) -> Option<PrimHit> {
        let oc = ray.origin - self.center;
        let b = oc.dot(ray.dir);
        let perpendicular = oc - b * ray.dir;
        let r2 = self.radius * self.radius;
        let discriminant = r2 - perpendicular.length_squared();
        if discriminant < 0.0 {
            return None;
        }
        let root = discriminant.sqrt();
        let near = -b - root;
        let far = -b + root;
        let t = if near > 0.0 { near } else { far };
        (t > 0.0 && t < t_max).then_some(PrimHit { t, u: 0.0, v: 0.0 })
    }
}
