//! [`GltfBsdf`]'s plain materials ([`GltfBsdf::is_plain`]: the diffuse and GGX
//! reflection lobes alone) at sixteen path vertices at once, one `f32x16` lane per
//! vertex, so that path mode shades a batch's plain hits sixteen per instruction
//! ([`crate::integrators::path`]). Lanes may hold different materials: every
//! parameter is per lane.
//!
//! The scalar code ([`super::gltf::GltfAt`]'s plain path, [`super::Frame`],
//! [`super::microfacet::Ggx::sample_visible`], [`super::lambert::cosine_hemisphere`])
//! is the reference: each function here is its scalar namesake's formula, operation
//! for operation in the same order (no fused multiply-adds), its branches turned
//! into lane masks; only `sin_cos` may round differently (`wide`'s sixteen-lane
//! polynomial against its four-lane one).

use std::f32::consts::{FRAC_1_PI, PI};

use wide::f32x16;

use super::gltf::GltfBsdf;
use crate::math::{Float, Vec3};

/// Vertices shaded at once.
pub const LANES: usize = 16;

type F = f32x16;

/// Sixteen vectors in structure-of-arrays form.
#[derive(Clone, Copy, Debug)]
pub struct V3 {
    /// The `x` components.
    pub x: F,
    /// The `y` components.
    pub y: F,
    /// The `z` components.
    pub z: F,
}

impl V3 {
    /// `v` in every lane.
    #[inline(always)]
    pub fn splat(v: Vec3) -> V3 {
        V3 {
            x: F::splat(v.x),
            y: F::splat(v.y),
            z: F::splat(v.z),
        }
    }

    /// Loads sixteen vectors.
    #[inline(always)]
    pub fn from_vecs(v: &[Vec3; LANES]) -> V3 {
        V3 {
            x: F::from(v.map(|v| v.x)),
            y: F::from(v.map(|v| v.y)),
            z: F::from(v.map(|v| v.z)),
        }
    }

    /// Lane `lane`.
    #[inline(always)]
    pub fn lane(&self, lane: usize) -> Vec3 {
        Vec3::new(
            self.x.as_array()[lane],
            self.y.as_array()[lane],
            self.z.as_array()[lane],
        )
    }

    /// glam's `dot`: `(x x' + y y') + z z'`.
    #[inline(always)]
    pub fn dot(self, o: V3) -> F {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    /// Per channel sum.
    #[inline(always)]
    pub fn plus(self, o: V3) -> V3 {
        V3 {
            x: self.x + o.x,
            y: self.y + o.y,
            z: self.z + o.z,
        }
    }

    /// Per channel difference.
    #[inline(always)]
    pub fn minus(self, o: V3) -> V3 {
        V3 {
            x: self.x - o.x,
            y: self.y - o.y,
            z: self.z - o.z,
        }
    }

    /// Per channel product.
    #[inline(always)]
    pub fn times(self, o: V3) -> V3 {
        V3 {
            x: self.x * o.x,
            y: self.y * o.y,
            z: self.z * o.z,
        }
    }

    /// Every channel times `s`.
    #[inline(always)]
    pub fn scale(self, s: F) -> V3 {
        V3 {
            x: self.x * s,
            y: self.y * s,
            z: self.z * s,
        }
    }

    /// Every channel over `s` (a division per channel, as glam's `Vec3 / f32`).
    #[inline(always)]
    pub fn over(self, s: F) -> V3 {
        V3 {
            x: self.x / s,
            y: self.y / s,
            z: self.z / s,
        }
    }

    /// glam's `normalize`: times `1 / sqrt(dot)`.
    #[inline(always)]
    fn normalize(self) -> V3 {
        self.scale(F::ONE / self.dot(self).sqrt())
    }

    /// glam's `max_element`: `x > m ? x : m` with `m = y > z ? y : z` (NaN loses
    /// only where it is compared first).
    #[inline(always)]
    pub fn max_element(self) -> F {
        let m = self.y.simd_gt(self.z).select(self.y, self.z);
        self.x.simd_gt(m).select(self.x, m)
    }

    /// Whether some channel is not zero (NaN is not).
    #[inline(always)]
    pub fn nonzero(self) -> F {
        self.x.simd_ne(F::ZERO) | self.y.simd_ne(F::ZERO) | self.z.simd_ne(F::ZERO)
    }

    /// `a` where `mask`, else `b`.
    #[inline(always)]
    pub fn select(mask: F, a: V3, b: V3) -> V3 {
        V3 {
            x: mask.select(a.x, b.x),
            y: mask.select(a.y, b.y),
            z: mask.select(a.z, b.z),
        }
    }

    /// glam's `lerp`: `self (1 - s) + rhs s`.
    #[inline(always)]
    fn lerp(self, rhs: V3, s: F) -> V3 {
        self.scale(F::ONE - s).plus(rhs.scale(s))
    }
}

/// A lane mask of the bits of `bits`: all ones in lane `i` if bit `i` is set.
#[inline(always)]
pub fn mask(bits: u32) -> F {
    F::from(std::array::from_fn::<Float, LANES, _>(|i| {
        Float::from_bits(if bits >> i & 1 == 1 { u32::MAX } else { 0 })
    }))
}

/// Sixteen vectors gathered lane by lane, as three arrays written a float at a
/// time (arrays of `Vec3`s read back as `f32x16`s stalled on store forwarding, a
/// tenth of the plain shading's time).
#[derive(Clone, Copy, Debug)]
pub struct V3Gather([[Float; LANES]; 3]);

impl V3Gather {
    /// `v` in every lane.
    #[inline(always)]
    pub fn splat(v: Vec3) -> V3Gather {
        V3Gather([[v.x; LANES], [v.y; LANES], [v.z; LANES]])
    }

    /// Sets lane `lane` to `v`.
    #[inline(always)]
    pub fn set(&mut self, lane: usize, v: Vec3) {
        self.0[0][lane] = v.x;
        self.0[1][lane] = v.y;
        self.0[2][lane] = v.z;
    }

    /// The sixteen vectors.
    #[inline(always)]
    pub fn load(&self) -> V3 {
        V3 {
            x: F::from(self.0[0]),
            y: F::from(self.0[1]),
            z: F::from(self.0[2]),
        }
    }
}

/// [`super::fresnel::schlick_weight`].
#[inline(always)]
fn schlick_weight(cos: F) -> F {
    let m = (F::ONE - cos.abs()).max(F::ZERO).min(F::ONE);
    let m2 = m * m;
    m2 * m2 * m
}

/// `f0 + (f90 - f0) w`, [`GltfAt`](super::gltf::GltfAt)'s dielectric Fresnel.
#[inline(always)]
fn fresnel(f0: V3, f90: F, w: F) -> V3 {
    f0.plus(
        V3 {
            x: f90 - f0.x,
            y: f90 - f0.y,
            z: f90 - f0.z,
        }
        .scale(w),
    )
}

/// `base + (1 - base) w`, the metal's Fresnel.
#[inline(always)]
fn metal_fresnel(base: V3, w: F) -> V3 {
    base.plus(V3::splat(Vec3::ONE).minus(base).scale(w))
}

/// The `mean` of [`super::gltf`].
#[inline(always)]
fn mean(v: V3) -> F {
    (v.x + v.y + v.z) * F::splat(1.0 / 3.0)
}

/// [`super::Frame`]s of sixteen normals.
#[derive(Clone, Copy, Debug)]
struct Frames {
    t: V3,
    b: V3,
    n: V3,
}

impl Frames {
    /// [`super::Frame::from_normal`].
    #[inline(always)]
    fn from_normal(n: V3) -> Frames {
        let sign = n.z.is_sign_negative().select(-F::ONE, F::ONE);
        let a = -F::ONE / (sign + n.z);
        let b = n.x * n.y * a;
        Frames {
            t: V3 {
                x: F::ONE + sign * n.x * n.x * a,
                y: sign * b,
                z: -sign * n.x,
            },
            b: V3 {
                x: b,
                y: sign + n.y * n.y * a,
                z: -n.y,
            },
            n,
        }
    }

    #[inline(always)]
    fn to_local(self, v: V3) -> V3 {
        V3 {
            x: v.dot(self.t),
            y: v.dot(self.b),
            z: v.dot(self.n),
        }
    }

    #[inline(always)]
    fn to_world(self, v: V3) -> V3 {
        self.t
            .scale(v.x)
            .plus(self.b.scale(v.y))
            .plus(self.n.scale(v.z))
    }
}

/// What [`PlainVertices::at`] gathers, one lane at a time: plain materials and the
/// vertices they are seen at.
#[derive(Clone, Debug)]
pub struct PlainGather {
    wo: V3Gather,
    ns: V3Gather,
    ng: V3Gather,
    base: V3Gather,
    f0: V3Gather,
    metallic: [Float; LANES],
    alpha: [Float; LANES],
    f90: [Float; LANES],
}

impl Default for PlainGather {
    /// Every lane a white dielectric seen head on (lanes left unset shade
    /// something harmless).
    fn default() -> PlainGather {
        PlainGather {
            wo: V3Gather::splat(Vec3::Z),
            ns: V3Gather::splat(Vec3::Z),
            ng: V3Gather::splat(Vec3::Z),
            base: V3Gather::splat(Vec3::ONE),
            f0: V3Gather::splat(Vec3::splat(0.04)),
            metallic: [0.0; LANES],
            alpha: [0.25; LANES],
            f90: [1.0; LANES],
        }
    }
}

impl PlainGather {
    /// Sets lane `lane` to the plain material `bsdf` seen from the world direction
    /// `wo`, with unit shading normal `ns` and geometric normal `ng` (both facing
    /// `wo`, as [`super::Bsdf::at`] takes them). False (and nothing set) if `bsdf`
    /// is not plain.
    #[inline(always)]
    pub fn set(&mut self, lane: usize, bsdf: &GltfBsdf, wo: Vec3, ns: Vec3, ng: Vec3) -> bool {
        let Some(p) = bsdf.plain_parameters() else {
            return false;
        };
        self.wo.set(lane, wo);
        self.ns.set(lane, ns);
        self.ng.set(lane, ng);
        self.base.set(lane, p.base);
        self.f0.set(lane, p.f0);
        self.metallic[lane] = p.metallic;
        self.alpha[lane] = p.alpha;
        self.f90[lane] = p.f90;
        true
    }

    /// The sixteen vertices: frames, lobe probabilities and what `wo` alone
    /// decides ([`GltfBsdf::at`]).
    #[inline(always)]
    pub fn at(&self) -> PlainVertices {
        let frames = Frames::from_normal(self.ns.load());
        let wo = frames.to_local(self.wo.load());
        let base = self.base.load();
        let f0 = self.f0.load();
        let (metallic, alpha, f90) = (
            F::from(self.metallic),
            F::from(self.alpha),
            F::from(self.f90),
        );
        let a2 = alpha * alpha;
        let above = wo.z.simd_gt(F::ZERO);
        let visibility_o = (a2 + (F::ONE - a2) * wo.z * wo.z).sqrt();
        let pdf_scale = F::splat(0.5) / (wo.z + visibility_o);
        // `GltfAt::lobe_probabilities` without coat, sheen or transmission (whose
        // weights are exact zeros and leave the sums' bits alone).
        let w = schlick_weight(wo.z);
        let fd = fresnel(f0, f90, w);
        let fm = metal_fresnel(base, w);
        let dielectric = F::ONE - metallic;
        let under = dielectric * (F::ONE - fd.max_element()) * mean(base);
        let specular = dielectric * mean(fd) + metallic * mean(fm);
        let total = under + specular;
        let valid = above & total.simd_gt(F::ZERO) & total.is_finite();
        let scale = F::ONE / total;
        PlainVertices {
            frames,
            ng: self.ng.load(),
            wo,
            base,
            f0,
            metallic,
            f90,
            a2,
            alpha,
            above,
            visibility_o: above.select(visibility_o, F::ZERO),
            pdf_scale: above.select(pdf_scale, F::ZERO),
            p_diffuse: valid.select(under * scale, F::ZERO),
            p_specular: valid.select(specular * scale, F::ZERO),
        }
    }
}

/// Sixteen plain materials each seen from its `wo` ([`PlainGather::at`]): the
/// lanes of [`super::BsdfAt`] for a plain glTF material.
#[derive(Clone, Copy, Debug)]
pub struct PlainVertices {
    frames: Frames,
    ng: V3,
    /// `wo` in the local frames.
    wo: V3,
    base: V3,
    f0: V3,
    metallic: F,
    f90: F,
    alpha: F,
    a2: F,
    /// `wo.z > 0`.
    above: F,
    visibility_o: F,
    pdf_scale: F,
    p_diffuse: F,
    p_specular: F,
}

/// Sixteen [`super::ScatterSample`]s of plain materials (reflections of non-delta
/// lobes: `delta` false, `eta` 1).
#[derive(Clone, Copy, Debug)]
pub struct PlainSamples {
    /// Where a lane has a sample (all bits set) or scatters nothing (zero).
    pub valid: F,
    /// Unit world directions.
    pub wi: V3,
    /// `f |cos| / pdf`.
    pub weight: V3,
    /// Densities.
    pub pdf: F,
}

impl PlainVertices {
    /// The unit shading normals, in the world.
    #[inline(always)]
    pub fn shading_normals(&self) -> V3 {
        self.frames.n
    }

    /// The unit geometric normals, in the world.
    #[inline(always)]
    pub fn geometric_normals(&self) -> V3 {
        self.ng
    }

    /// [`super::BsdfAt::has_smooth_lobes`], as a lane mask.
    #[inline(always)]
    pub fn has_smooth_lobes(&self) -> F {
        self.p_diffuse.simd_gt(F::ZERO) | self.p_specular.simd_gt(F::ZERO)
    }

    /// [`super::BsdfAt::eval_and_pdf`] of world directions `wi`; in the lanes of
    /// `past_terminator`, [`super::BsdfAt::eval_past_terminator`] with a density of
    /// 0 where `wi` lies below the geometric surface.
    #[inline(always)]
    pub fn eval_and_pdf(&self, wi: V3, past_terminator: F) -> (V3, F) {
        let agrees = agrees(wi, self.frames.n, self.ng);
        let local = self.frames.to_local(wi);
        let ok = (agrees | past_terminator) & self.above & local.z.simd_gt(F::ZERO);
        let (f, pdf) = self.local_eval_pdf(local);
        (
            V3::select(ok, f, V3::splat(Vec3::ZERO)),
            (ok & agrees).select(pdf, F::ZERO),
        )
    }

    /// `GltfAt::plain_eval_pdf` for local `wi` with `wi.z > 0`.
    #[inline(always)]
    fn local_eval_pdf(&self, wi: V3) -> (V3, F) {
        let h = self.wo.plus(wi).normalize();
        let (d, specular) = self.d_dv(h, wi);
        let pdf_diffuse = self.p_diffuse * (wi.z * F::splat(FRAC_1_PI));
        let specular_pdf = self
            .wo
            .dot(h)
            .simd_le(F::ZERO)
            .select(F::ZERO, self.pdf_scale * d);
        let pdf = self
            .p_specular
            .simd_gt(F::ZERO)
            .select(pdf_diffuse + self.p_specular * specular_pdf, pdf_diffuse);
        (self.reflected(h, specular), pdf)
    }

    /// `GltfAt::plain_d_dv`.
    #[inline(always)]
    fn d_dv(&self, h: V3, wi: V3) -> (F, F) {
        let a2 = self.a2;
        let t = h.z * h.z * (a2 - F::ONE) + F::ONE;
        let denominator = self.visibility_denominator(wi);
        let product = F::splat(PI) * t * t * denominator;
        let q = F::ONE / product;
        let mut d = a2 * denominator * q;
        let mut dv = F::splat(0.5) * a2 * q;
        let small = product.is_nan() | product.simd_lt(F::splat(Float::MIN_POSITIVE));
        if small.any() {
            // The two quotients apart, as `Ggx::d` and `GltfAt::visibility`.
            let d0 = a2 / (F::splat(PI) * t * t);
            let v0 = denominator
                .simd_gt(F::ZERO)
                .select(F::splat(0.5) / denominator, F::ZERO);
            d = small.select(d0, d);
            dv = small.select(d0 * v0, dv);
        }
        let up = h.z.simd_gt(F::ZERO);
        (up.select(d, F::ZERO), up.select(dv, F::ZERO))
    }

    /// `GltfAt::visibility_denominator`.
    #[inline(always)]
    fn visibility_denominator(&self, wi: V3) -> F {
        let a2 = self.a2;
        let ci = wi.z.abs();
        ci * self.visibility_o + self.wo.z * (a2 + (F::ONE - a2) * ci * ci).sqrt()
    }

    /// `GltfAt::reflected` without compensation (`D V` is `specular`).
    #[inline(always)]
    fn reflected(&self, h: V3, specular: F) -> V3 {
        let w = schlick_weight(self.wo.dot(h));
        let fd = fresnel(self.f0, self.f90, w);
        let diffuse = self
            .base
            .scale((F::ONE - fd.max_element()) * F::splat(FRAC_1_PI));
        let dielectric = fd.scale(specular).plus(diffuse);
        let metal = metal_fresnel(self.base, w).scale(specular);
        dielectric.lerp(metal, self.metallic)
    }

    /// [`super::BsdfAt::sample`]: `u_lobe` picks the lobe, `u` the direction, lane by
    /// lane; `wi` in the world.
    #[inline(always)]
    pub fn sample(&self, u_lobe: F, u: [F; 2]) -> PlainSamples {
        let wo = self.wo;
        let specular_lobe = u_lobe.simd_ge(self.p_diffuse) & self.p_specular.simd_gt(F::ZERO);
        let (sin, cos) = (F::splat(2.0 * PI) * u[1]).sin_cos();

        // The specular lobe: `Ggx::sample_visible` and `GltfAt::plain_specular_sample`.
        let a = self.alpha;
        let v = V3 {
            x: a * wo.x,
            y: a * wo.y,
            z: wo.z,
        }
        .normalize();
        let z = (F::ONE - u[0]) * (F::ONE + v.z) - v.z;
        let sin_theta = (F::ONE - z * z).max(F::ZERO).sqrt();
        let h = V3 {
            x: a * (sin_theta * cos + v.x),
            y: a * (sin_theta * sin + v.y),
            z: (z + v.z).max(F::splat(1e-6)),
        }
        .normalize();
        let o = wo.dot(h);
        let reflected = h.scale(o + o).minus(wo);
        let specular_ok = reflected.z.simd_gt(F::ZERO) & o.simd_gt(F::ZERO);
        let metal = self.p_diffuse.simd_eq(F::ZERO);
        // A metal's: `D` for the density alone.
        let t = h.z * h.z * (self.a2 - F::ONE) + F::ONE;
        let d =
            h.z.simd_gt(F::ZERO)
                .select(self.a2 / (F::splat(PI) * t * t), F::ZERO);
        let metal_pdf = self.p_specular * (self.pdf_scale * d);
        let w = schlick_weight(o);
        let fm = metal_fresnel(self.base, w);
        let fd = fresnel(self.f0, self.f90, w);
        let scale = self.visibility_denominator(reflected) * self.pdf_scale * self.p_specular;
        let metal_weight = fd
            .lerp(fm, self.metallic)
            .scale(F::splat(0.5) * reflected.z / scale);
        // A mixture's: `D V` and the whole density.
        let (d, dv) = self.d_dv(h, reflected);
        let mixed_pdf = self.p_diffuse * (reflected.z * F::splat(FRAC_1_PI))
            + self.p_specular * (self.pdf_scale * d);
        let mixed_weight = self.reflected(h, dv).scale(reflected.z / mixed_pdf);
        let specular_pdf = metal.select(metal_pdf, mixed_pdf);
        let specular_weight = V3::select(metal, metal_weight, mixed_weight);

        // The diffuse lobe: `cosine_hemisphere` and `GltfAt::plain_eval_pdf`.
        let r = u[0].sqrt();
        let diffuse = V3 {
            x: r * cos,
            y: r * sin,
            z: (F::ONE - u[0]).max(F::ZERO).sqrt(),
        };
        let diffuse_ok = self.p_diffuse.simd_gt(F::ZERO) & diffuse.z.simd_gt(F::ZERO);
        let (f, diffuse_pdf) = self.local_eval_pdf(diffuse);
        let diffuse_weight = f.scale(diffuse.z).over(diffuse_pdf);

        let wi = V3::select(specular_lobe, reflected, diffuse);
        let pdf = specular_lobe.select(specular_pdf, diffuse_pdf);
        let weight = V3::select(specular_lobe, specular_weight, diffuse_weight);
        let world = self.frames.to_world(wi);
        let valid = self.above
            & specular_lobe.select(specular_ok, diffuse_ok)
            & !pdf.is_nan()
            & pdf.simd_gt(F::ZERO)
            & agrees(world, self.frames.n, self.ng);
        PlainSamples {
            valid,
            wi: world,
            weight,
            pdf,
        }
    }
}

/// `super::agrees`: whether `wi` lies on the same side of the shading and the
/// geometric surface.
#[inline(always)]
fn agrees(wi: V3, ns: V3, ng: V3) -> F {
    !(wi.dot(ns).simd_gt(F::ZERO) ^ wi.dot(ng).simd_gt(F::ZERO))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bxdfs::Bsdf;
    use crate::material::pbr::{PbrMaterial, PbrValues};
    use crate::math::Vec2;

    /// A generator of numbers in [0, 1) (SplitMix64), for random inputs.
    struct Numbers(u64);

    impl Numbers {
        fn next(&mut self) -> Float {
            self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            ((z ^ (z >> 31)) >> 40) as Float / (1u64 << 24) as Float
        }

        /// A unit vector, uniform on the sphere.
        fn direction(&mut self) -> Vec3 {
            let z = 1.0 - 2.0 * self.next();
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = 2.0 * PI * self.next();
            Vec3::new(r * phi.cos(), r * phi.sin(), z)
        }
    }

    /// A plain material's values of random colour, metallic, roughness and
    /// specular.
    fn material(numbers: &mut Numbers) -> PbrValues {
        let metallic = match numbers.next() {
            m if m < 0.3 => 0.0,
            m if m < 0.6 => 1.0,
            m => m,
        };
        PbrMaterial {
            base_color: Vec3::new(numbers.next(), numbers.next(), numbers.next()),
            metallic,
            roughness: 0.02 + 0.98 * numbers.next(),
            specular: 0.5 + 0.5 * numbers.next(),
            ..PbrMaterial::default()
        }
        .constants()
    }

    /// A shading normal near `ng` (tilted up to about 35 degrees, as interpolated
    /// normals are), sometimes equal to it.
    fn shading_normal(numbers: &mut Numbers, ng: Vec3) -> Vec3 {
        if numbers.next() < 0.2 {
            return ng;
        }
        (ng + numbers.direction() * 0.6).normalize()
    }

    fn close(a: Float, b: Float) -> bool {
        a == b || (a - b).abs() <= 1e-5 * a.abs().max(b.abs())
    }

    fn close3(a: Vec3, b: Vec3) -> bool {
        (0..3).all(|c| close(a[c], b[c]))
    }

    /// One batch of random vertices: every lane's value, density and sample must
    /// equal the scalar BSDF's (`Bsdf::at` in world space); the number of lanes
    /// that sampled a direction. With `wrong_lane`, that lane's metallic is changed
    /// in the lanes' copy only, and the check must notice.
    fn check_batch(numbers: &mut Numbers, wrong_lane: Option<usize>) -> Result<usize, String> {
        let mut gather = PlainGather::default();
        let mut scalar = Vec::new();
        for lane in 0..LANES {
            let values = material(numbers);
            let g = GltfBsdf::new(&values);
            let ng = numbers.direction();
            let ns = shading_normal(numbers, ng);
            // `wo` on the geometric normal's side, grazing now and then and
            // sometimes below the shading surface.
            let mut wo = numbers.direction();
            if wo.dot(ng) < 0.0 {
                wo = -wo;
            }
            if numbers.next() < 0.1 {
                wo = (wo - ng * wo.dot(ng) * 0.999).normalize();
            }
            let copy = if wrong_lane == Some(lane) {
                let metallic = if values.metallic > 0.5 { 0.5 } else { 1.0 };
                GltfBsdf::new(&PbrValues { metallic, ..values })
            } else {
                g
            };
            assert!(gather.set(lane, &copy, wo, ns, ng));
            scalar.push((Bsdf::Gltf(g), wo, ns, ng));
        }
        let lanes = gather.at();
        let wi = std::array::from_fn(|_| numbers.direction());
        let u_lobe: [Float; LANES] = std::array::from_fn(|_| numbers.next());
        let u: [[Float; LANES]; 2] =
            std::array::from_fn(|_| std::array::from_fn(|_| numbers.next()));
        let (f, pdf) = lanes.eval_and_pdf(V3::from_vecs(&wi), F::ZERO);
        let smooth = lanes.has_smooth_lobes().to_bitmask();
        let samples = lanes.sample(F::from(u_lobe), u.map(F::from));
        let valid = samples.valid.to_bitmask();
        let mut sampled = 0;
        for (lane, (bsdf, wo, ns, ng)) in scalar.iter().enumerate() {
            let at = bsdf.at(*wo, *ns, *ng, Vec3::ZERO, Vec3::ZERO, true);
            let (f0, pdf0) = at.eval_and_pdf(wi[lane]);
            let here = format!("lane {lane}: {bsdf:?} wo {wo} ns {ns} ng {ng}");
            if at.has_smooth_lobes() != (smooth >> lane & 1 == 1) {
                return Err(format!("{here}: has_smooth_lobes"));
            }
            if !close3(f.lane(lane), f0) || !close(pdf.as_array()[lane], pdf0) {
                let got = (f.lane(lane), pdf.as_array()[lane]);
                return Err(format!("{here} wi {}: {got:?} vs {f0} {pdf0}", wi[lane]));
            }
            let u_here = Vec2::new(u[0][lane], u[1][lane]);
            let expected = at.sample(u_lobe[lane], u_here);
            match (expected, valid >> lane & 1 == 1) {
                (None, false) => {}
                (Some(s), true) => {
                    let got = (samples.wi.lane(lane), samples.weight.lane(lane));
                    let pdf = samples.pdf.as_array()[lane];
                    if !(close3(got.0, s.wi) && close3(got.1, s.weight) && close(pdf, s.pdf)) {
                        return Err(format!("{here} u {u_here}: {got:?} {pdf} vs {s:?}"));
                    }
                    sampled += 1;
                }
                (s, _) => {
                    return Err(format!(
                        "{here} u {u_here}: sample {s:?} vs lanes' {valid:b}"
                    ));
                }
            }
        }
        Ok(sampled)
    }

    /// The sixteen-lane plain BSDF equals the scalar one lane by lane (value,
    /// density, sampled direction, weight and density, to 1e-5 relative) on random
    /// materials mixed across the lanes (metals, dielectrics and blends of random
    /// roughness), random shading normals, grazing and below-horizon directions.
    #[test]
    fn lanes_agree_with_the_scalar_bsdf() {
        let mut numbers = Numbers(7);
        let sampled: usize = (0..400)
            .map(|_| check_batch(&mut numbers, None).unwrap())
            .sum();
        // Most lanes sample a direction: the comparison is not of empty samples.
        assert!(sampled > 400 * LANES / 2, "{sampled}");
    }

    /// The comparison above notices a single lane whose material differs, and
    /// names it (unless that lane's `wo` is below its shading surface, where both
    /// materials scatter nothing).
    #[test]
    fn a_wrong_lane_is_noticed() {
        let mut numbers = Numbers(7);
        let mut failed = 0;
        for i in 0..40 {
            if let Err(message) = check_batch(&mut numbers, Some(i % LANES)) {
                assert!(
                    message.starts_with(&format!("lane {}:", i % LANES)),
                    "{message}"
                );
                failed += 1;
            }
        }
        assert!(failed >= 30, "{failed} of 40");
    }
}
