//! Vector math shared by every stage: the float type, rays, boxes, reflection and
//! refraction.
//!
//! The renderer computes in `f32` ([`Float`]): the BVH nodes, triangle kernels and film
//! are all single precision, which halves memory traffic in the hot loops. The
//! reference geometry vectors were checked at 1e-9 in double precision; in `f32` the
//! geometry tests use a tolerance of 1e-4 relative to the magnitudes involved (about
//! 2^-13, leaving room for the ~10 roundings of a quadratic solve on values near 5).

pub use glam::{Vec2, Vec3};

/// The one floating-point type of the renderer.
pub type Float = f32;

/// The largest [`Float`] below 1: where a value in `[0, 1)` must stay below 1.
pub const ONE_BELOW_ONE: Float = 1.0 - Float::EPSILON / 2.0;

/// A half-line `origin + t * dir`, `t >= 0`, with a unit direction.
///
/// Laid out as six `f32` (origin, then direction), so that packets of rays can be
/// read with vector loads.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct Ray {
    /// Where the ray starts.
    pub origin: Vec3,
    /// Unit direction.
    pub dir: Vec3,
}

impl Ray {
    /// A ray from `origin` along `dir`, which is normalized here.
    ///
    /// # Panics
    /// In debug builds, if `dir` has zero length or is not finite.
    #[inline]
    pub fn new(origin: Vec3, dir: Vec3) -> Ray {
        let dir = dir.normalize();
        debug_assert!(dir.is_finite(), "ray direction must be finite and non-zero");
        Ray { origin, dir }
    }

    /// The point at distance `t` along the ray.
    #[inline]
    pub fn at(&self, t: Float) -> Vec3 {
        self.origin + self.dir * t
    }
}

/// An axis-aligned bounding box. The empty box has `min = +inf`, `max = -inf`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Lower corner.
    pub min: Vec3,
    /// Upper corner.
    pub max: Vec3,
}

impl Default for Aabb {
    fn default() -> Self {
        Aabb::EMPTY
    }
}

impl Aabb {
    /// The box that contains nothing; the identity of [`Aabb::union`].
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::splat(Float::INFINITY),
        max: Vec3::splat(Float::NEG_INFINITY),
    };

    /// The smallest box holding all `points`.
    pub fn from_points(points: &[Vec3]) -> Aabb {
        points.iter().fold(Aabb::EMPTY, |b, &p| b.grow(p))
    }

    /// This box grown to contain `p`.
    #[inline]
    pub fn grow(self, p: Vec3) -> Aabb {
        Aabb {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }

    /// The smallest box containing both boxes.
    #[inline]
    pub fn union(self, other: Aabb) -> Aabb {
        Aabb {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    /// Whether the box holds no point.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x || self.min.y > self.max.y || self.min.z > self.max.z
    }

    /// The centre point.
    #[inline]
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }

    /// Half the surface area (the constant factor cancels in SAH ratios); 0 when empty.
    #[inline]
    pub fn half_area(&self) -> Float {
        if self.is_empty() {
            return 0.0;
        }
        let e = self.max - self.min;
        e.x * e.y + e.y * e.z + e.z * e.x
    }

    /// Whether `other` lies inside this box (boundaries included).
    pub fn contains(&self, other: &Aabb) -> bool {
        other.is_empty() || (self.min.cmple(other.min).all() && other.max.cmple(self.max).all())
    }
}

/// Mirror reflection of direction `d` about the unit normal `n` (either orientation).
#[inline]
pub fn reflect(d: Vec3, n: Vec3) -> Vec3 {
    d - 2.0 * d.dot(n) * n
}

/// Refraction of the unit direction `d` through a surface with unit normal `n` facing
/// against `d`, where `eta = n1 / n2` (index of the medium left over the one entered).
///
/// Returns `None` on total internal reflection, so it cannot be traced by accident, and
/// when `eta` is so extreme (an index of 0 or near it) that no finite direction exists.
#[inline]
pub fn refract(d: Vec3, n: Vec3, eta: Float) -> Option<Vec3> {
    let cos_i = -d.dot(n);
    let k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
    // NaN comes from `inf * 0` when `eta` is infinite (an index of 0).
    if k.is_nan() || k < 0.0 {
        return None;
    }
    let t = eta * d + (eta * cos_i - k.sqrt()) * n;
    try_unit(t)
}

/// The camera's right and up directions for the unit direction `backward` (from the
/// point looked at to the eye) and world up `up` (any non-zero length), as
/// `Camera::with_up` takes them: when `backward` is parallel to `up`, `right` is +x
/// made perpendicular to `backward`, or +z if the camera looks along x.
pub fn view_basis(backward: Vec3, up: Vec3) -> (Vec3, Vec3) {
    let up = try_unit(up).unwrap_or(Vec3::Y);
    let right = up.cross(backward).try_normalize().unwrap_or_else(|| {
        (Vec3::X - backward * Vec3::X.dot(backward))
            .try_normalize()
            .unwrap_or(Vec3::Z)
    });
    (right, backward.cross(right))
}

/// The unit vector along `v`, or `None` if `v` is zero or not finite.
///
/// Unlike glam's `try_normalize` it also works when the squared length of `v`
/// overflows or underflows `f32` (components beyond about 1e19 or below 1e-19), by
/// scaling the largest component to 1 first.
#[inline]
pub fn try_unit(v: Vec3) -> Option<Vec3> {
    let largest = v.abs().max_element();
    if !(largest > 0.0 && largest.is_finite()) {
        return None;
    }
    (v / largest).try_normalize()
}

/// glam's `Vec3::dot` of sixteen vectors at once, in structure-of-arrays form: lane by
/// lane `(x * x' + y * y') + z * z'`, the same bits as the scalar dot (for the SIMD
/// paths that must match the single-ray code exactly).
#[inline(always)]
pub(crate) fn dot_lanes(a: [wide::f32x16; 3], b: [wide::f32x16; 3]) -> wide::f32x16 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The index of the smallest of `values` among the bits set in `mask`, the lowest
/// index on equal values (as a scalar loop keeping only strictly smaller ones);
/// `None` for an empty mask. Bits at or past `N` must be clear.
#[inline(always)]
pub(crate) fn nearest_in_mask<const N: usize>(mut mask: u32, values: &[Float; N]) -> Option<usize> {
    if mask == 0 {
        return None;
    }
    let mut best = mask.trailing_zeros() as usize;
    mask &= mask - 1;
    while mask != 0 {
        let index = mask.trailing_zeros() as usize;
        mask &= mask - 1;
        if values[index] < values[best] {
            best = index;
        }
    }
    Some(best)
}

/// The sine and cosine of `x` (radians), inlined: Agner Fog's polynomials as the
/// `wide` crate vectorizes them, as accurate as the C library's `sincosf` for path
/// mode's angles in `[0, 2 pi)`, without a call per sampled direction.
#[inline(always)]
pub fn sin_cos(x: Float) -> (Float, Float) {
    let (sin, cos) = wide::f32x4::splat(x).sin_cos();
    (sin.as_array()[0], cos.as_array()[0])
}

/// `v` with NaN channels set to 0 and infinite ones to the largest finite value of
/// their sign: where absurd scene values (lights of 1e38, say) overflow, the pixel
/// saturates instead of turning the image's tone mapping into NaN.
#[inline]
pub fn saturate_finite(v: Vec3) -> Vec3 {
    let clamped = v.clamp(Vec3::splat(Float::MIN), Vec3::splat(Float::MAX));
    Vec3::select(v.is_nan_mask(), Vec3::ZERO, clamped)
}

/// Uniform numbers in `[0, 1)` from Marsaglia's xorshift generator seeded with
/// `state` (not zero): a deterministic stream for the library's tests.
#[cfg(test)]
pub(crate) fn xorshift(mut state: u64) -> impl FnMut() -> Float {
    move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as Float / (1u64 << 24) as Float
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refract_straight_through_keeps_direction() {
        let d = Vec3::new(0.0, 0.0, -1.0);
        let t = refract(d, Vec3::Z, 1.5).unwrap();
        assert!((t - d).length() < 1e-6);
    }

    #[test]
    fn refract_grazing_from_dense_medium_is_total_internal_reflection() {
        let d = Vec3::new(1.0, 0.0, -0.1).normalize();
        assert_eq!(refract(d, Vec3::Z, 1.5), None);
    }

    #[test]
    fn refract_with_extreme_index_gives_no_direction() {
        let d = Vec3::new(0.0, 0.0, -1.0);
        // Index 0 makes eta infinite: straight on, eta^2 * 0 is NaN.
        assert_eq!(refract(d, Vec3::Z, Float::INFINITY), None);
        let slanted = Vec3::new(0.6, 0.0, -0.8);
        assert_eq!(refract(slanted, Vec3::Z, 1e30), None);
    }

    #[test]
    fn try_unit_handles_huge_tiny_zero_and_non_finite_vectors() {
        let huge = try_unit(Vec3::new(3e30, 4e30, 0.0)).unwrap();
        assert!((huge - Vec3::new(0.6, 0.8, 0.0)).length() < 1e-6);
        let tiny = try_unit(Vec3::new(0.0, 3e-30, -4e-30)).unwrap();
        assert!((tiny - Vec3::new(0.0, 0.6, -0.8)).length() < 1e-6);
        assert_eq!(try_unit(Vec3::ZERO), None);
        assert_eq!(try_unit(Vec3::new(1.0, Float::NAN, 0.0)), None);
        assert_eq!(try_unit(Vec3::new(Float::INFINITY, 0.0, 0.0)), None);
    }

    #[test]
    fn saturate_finite_clamps_infinities_and_zeroes_nan() {
        let v = saturate_finite(Vec3::new(Float::INFINITY, Float::NAN, -Float::INFINITY));
        assert_eq!(v, Vec3::new(Float::MAX, 0.0, Float::MIN));
        assert_eq!(saturate_finite(Vec3::ONE), Vec3::ONE);
    }

    #[test]
    fn empty_box_has_zero_area_and_is_contained_everywhere() {
        assert_eq!(Aabb::EMPTY.half_area(), 0.0);
        let unit = Aabb::from_points(&[Vec3::ZERO, Vec3::ONE]);
        assert!(unit.contains(&Aabb::EMPTY));
        assert!(!Aabb::EMPTY.contains(&unit));
    }

    #[test]
    fn sin_cos_matches_the_c_library_over_a_turn() {
        for i in 0..=4096 {
            let x = 2.0 * std::f32::consts::PI * i as Float / 4096.0;
            let (sin, cos) = sin_cos(x);
            assert!(
                (sin - x.sin()).abs() < 4e-7,
                "sin {x}: {sin} vs {}",
                x.sin()
            );
            assert!(
                (cos - x.cos()).abs() < 4e-7,
                "cos {x}: {cos} vs {}",
                x.cos()
            );
        }
    }
}
