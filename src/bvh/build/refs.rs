//! What the builder moves around: one 32-byte reference per primitive (its box and
//! original index), and boxes kept in SIMD registers for the inner loops.

use glam::{BVec4A, Vec3A, Vec4};
use wide::f32x8;

use crate::math::{Aabb, Float};

/// A primitive's box with its original index in the spare lane of `min`: 32 bytes,
/// moved around during the build instead of indexing the caller's arrays.
#[derive(Clone, Copy, Debug)]
#[repr(C)]
pub(super) struct PrimRef {
    min_and_index: Vec4,
    max: Vec4,
}

// SAFETY: `PrimRef` is plain `f32` lanes, for which all-zero bits are 0.0.
unsafe impl bytemuck::Zeroable for PrimRef {}
// SAFETY: two `Vec4`s of `f32`, `repr(C)`, no padding; any bits are valid.
unsafe impl bytemuck::Pod for PrimRef {}

/// Keeps x, y, z and clears w. The index bits in `min_and_index.w` read as a
/// denormal float, and arithmetic on denormals takes a microcode assist on x86 (over
/// a hundred cycles): the spare lane must be zero before any SIMD arithmetic.
const XYZ: BVec4A = BVec4A::from_array([true, true, true, false]);

impl PrimRef {
    pub(super) fn new(bounds: Aabb, index: usize) -> PrimRef {
        PrimRef {
            min_and_index: bounds.min.extend(f32::from_bits(index as u32)),
            max: bounds.max.extend(0.0),
        }
    }
    #[inline(always)]
    pub(super) fn min(&self) -> Vec3A {
        Vec3A::from_vec4(Vec4::select(XYZ, self.min_and_index, Vec4::ZERO))
    }
    #[inline(always)]
    pub(super) fn max(&self) -> Vec3A {
        Vec3A::from_vec4(self.max)
    }
    #[inline(always)]
    pub(super) fn index(&self) -> u32 {
        self.min_and_index.w.to_bits()
    }
    /// The box as eight lanes: `min` x, y, z, 0, then `max` x, y, z negated, 0,
    /// the bins' form (see `bins::AxisBins`). One load, one `and`, one `xor`.
    #[inline(always)]
    pub(super) fn lanes(&self) -> f32x8 {
        // Clears the index bits of lane 3, flips the sign of lanes 4 to 6.
        const KEEP: [u32; 8] = [!0, !0, !0, 0, !0, !0, !0, !0];
        const FLIP: [u32; 8] = [0, 0, 0, 0, 1 << 31, 1 << 31, 1 << 31, 0];
        let lanes: [f32; 8] = bytemuck::cast(*self);
        let bits = |mask: [u32; 8]| f32x8::new(mask.map(f32::from_bits));
        (f32x8::new(lanes) & bits(KEEP)) ^ bits(FLIP)
    }
    /// [`PrimRef::centroid2`] as a box's eight lanes (see `bins::AxisBins`): `c`,
    /// 0, then `-c`, 0, each lane the same float as `min + max` or its negation.
    /// [`PrimRef::lanes`] `[m, -M]` minus its halves swapped `[-M, m]`.
    #[inline(always)]
    pub(super) fn centroid_lanes(&self) -> f32x8 {
        let lanes = self.lanes();
        lanes - swap_halves(lanes)
    }
    /// Twice the centroid: the factor 1/2 cancels in every comparison.
    #[inline(always)]
    pub(super) fn centroid2(&self) -> Vec3A {
        self.min() + self.max()
    }
    /// One coordinate of [`PrimRef::centroid2`], read from memory at an offset
    /// rather than picked out of a register by a jump on `axis`.
    #[inline(always)]
    pub(super) fn centroid2_on(&self, axis: usize) -> Float {
        let min: &[f32; 4] = self.min_and_index.as_ref();
        let max: &[f32; 4] = self.max.as_ref();
        min[axis] + max[axis]
    }
}

/// Lanes 4 to 7 of `x`, then lanes 0 to 3.
#[inline(always)]
fn swap_halves(x: f32x8) -> f32x8 {
    #[cfg(all(target_arch = "x86_64", target_feature = "avx"))]
    {
        use std::arch::x86_64::{__m256, _mm256_permute2f128_ps};
        let v: __m256 = bytemuck::cast(x);
        // SAFETY: AVX is enabled at compile time (the `cfg` above).
        bytemuck::cast(unsafe { _mm256_permute2f128_ps::<1>(v, v) })
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx")))]
    {
        let [a, b, c, d, e, f, g, h] = x.to_array();
        f32x8::new([e, f, g, h, a, b, c, d])
    }
}

/// A box in SIMD registers, for the build's inner loops.
#[derive(Clone, Copy, Debug)]
pub(super) struct Bounds {
    pub(super) min: Vec3A,
    pub(super) max: Vec3A,
}

impl Bounds {
    pub(super) const EMPTY: Bounds = Bounds {
        min: Vec3A::splat(Float::INFINITY),
        max: Vec3A::splat(Float::NEG_INFINITY),
    };
    #[inline(always)]
    pub(super) fn grow(&mut self, min: Vec3A, max: Vec3A) {
        self.min = self.min.min(min);
        self.max = self.max.max(max);
    }
    #[inline(always)]
    pub(super) fn union(self, other: Bounds) -> Bounds {
        Bounds {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }
    #[inline(always)]
    pub(super) fn half_area(&self) -> Float {
        // `e.x * e.y + e.y * e.z + e.z * e.x`, the products in one instruction.
        let e = (self.max - self.min).max(Vec3A::ZERO);
        (e * Vec3A::new(e.y, e.z, e.x)).element_sum()
    }
    pub(super) fn to_aabb(self) -> Aabb {
        Aabb {
            min: self.min.into(),
            max: self.max.into(),
        }
    }
}

/// The boxes and centroid bounds of some primitives.
pub(super) fn measure(refs: &[PrimRef]) -> (Bounds, Bounds) {
    refs.iter()
        .fold((Bounds::EMPTY, Bounds::EMPTY), |(mut b, mut c), r| {
            b.grow(r.min(), r.max());
            c.grow(r.centroid2(), r.centroid2());
            (b, c)
        })
}

/// `count` references to boxes of random sizes up to 1 along each axis, their
/// minimum corners spread over a cube of side `spread` centred on the origin: the
/// build tests' primitives.
#[cfg(test)]
pub(super) fn random_refs(rng: &mut impl rand::Rng, count: usize, spread: f32) -> Vec<PrimRef> {
    (0..count)
        .map(|i| {
            let min =
                glam::Vec3::new(rng.random(), rng.random(), rng.random()) * spread - spread / 2.0;
            let size = glam::Vec3::new(rng.random(), rng.random(), rng.random());
            PrimRef::new(
                Aabb {
                    min,
                    max: min + size,
                },
                i,
            )
        })
        .collect()
}
