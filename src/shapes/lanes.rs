//! Möller–Trumbore over SIMD lanes, one kernel for every width: four triangles of
//! a packet against one ray, a leaf's two packets (eight) against one ray, one
//! triangle against sixteen rays.

use wide::{f32x4, f32x8, f32x16};

#[cfg(doc)]
use super::Triangle;
use super::triangle::EDGE_SLACK;
use crate::math::Float;

/// The lane operations of a SIMD type that [`moller_trumbore`] uses.
pub(super) trait Lanes:
    Copy
    + std::ops::Add<Output = Self>
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<Output = Self>
    + std::ops::Div<Output = Self>
    + std::ops::BitAnd<Output = Self>
{
    fn splat(x: Float) -> Self;
    fn simd_ne(self, other: Self) -> Self;
    fn simd_ge(self, other: Self) -> Self;
    fn simd_le(self, other: Self) -> Self;
    fn simd_gt(self, other: Self) -> Self;
}

macro_rules! impl_lanes {
    ($t:ty) => {
        impl Lanes for $t {
            #[inline(always)]
            fn splat(x: Float) -> Self {
                <$t>::splat(x)
            }
            #[inline(always)]
            fn simd_ne(self, other: Self) -> Self {
                <$t>::simd_ne(self, other)
            }
            #[inline(always)]
            fn simd_ge(self, other: Self) -> Self {
                <$t>::simd_ge(self, other)
            }
            #[inline(always)]
            fn simd_le(self, other: Self) -> Self {
                <$t>::simd_le(self, other)
            }
            #[inline(always)]
            fn simd_gt(self, other: Self) -> Self {
                <$t>::simd_gt(self, other)
            }
        }
    };
}
impl_lanes!(f32x4);
impl_lanes!(f32x8);
impl_lanes!(f32x16);

/// Möller–Trumbore on every lane: triangles `v0`, `e1`, `e2` against rays `origin`,
/// `dir` (either side may be the same in every lane): which lanes hit with `t > 0`
/// (all bits set; the caller compares `t` with its own limit), and their `t`, `u`,
/// `v`. Each lane computes exactly what [`Triangle::intersect`] computes, operation
/// for operation and without fused multiply-adds, whatever the width.
#[inline(always)]
pub(super) fn moller_trumbore<L: Lanes>(
    origin: [L; 3],
    dir: [L; 3],
    v0: [L; 3],
    e1: [L; 3],
    e2: [L; 3],
) -> (L, L, L, L) {
    let [dx, dy, dz] = dir;
    let [e1x, e1y, e1z] = e1;
    let [e2x, e2y, e2z] = e2;
    // p = dir x e2, as glam's `Vec3::cross`.
    let px = dy * e2z - e2y * dz;
    let py = dz * e2x - e2z * dx;
    let pz = dx * e2y - e2x * dy;
    let det = e1x * px + e1y * py + e1z * pz;
    let inv_det = L::splat(1.0) / det;
    let sx = origin[0] - v0[0];
    let sy = origin[1] - v0[1];
    let sz = origin[2] - v0[2];
    let u = (sx * px + sy * py + sz * pz) * inv_det;
    // q = s x e1.
    let qx = sy * e1z - e1y * sz;
    let qy = sz * e1x - e1z * sx;
    let qz = sx * e1y - e1x * sy;
    let v = (dx * qx + dy * qy + dz * qz) * inv_det;
    let t = (e2x * qx + e2y * qy + e2z * qz) * inv_det;
    let low = L::splat(-EDGE_SLACK);
    let high = L::splat(1.0 + EDGE_SLACK);
    let zero = L::splat(0.0);
    let valid = det.simd_ne(zero)
        & u.simd_ge(low)
        & u.simd_le(high)
        & v.simd_ge(low)
        & (u + v).simd_le(high)
        & t.simd_gt(zero);
    (valid, t, u, v)
}
