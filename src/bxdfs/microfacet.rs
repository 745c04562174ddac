//! The GGX (Trowbridge-Reitz) microfacet distribution as glTF's Appendix B defines
//! it: `D = alpha^2 / (pi ((n.h)^2 (alpha^2 - 1) + 1)^2)` with `alpha = roughness^2`,
//! the height-correlated Smith masking-shadowing term, and sampling of the normals
//! visible from `wo` (Heitz's 2018 distribution, drawn on spherical caps as Dupuy and
//! Benyoub 2023 do), whose density cancels most of `D G`.
//!
//! [`GgxReflection`] is the lobe `D V` with `V = G2 / (4 |n.wo| |n.wi|)`, without a
//! Fresnel factor: glTF's model weighs it by Schlick's Fresnel outside
//! ([`super::gltf`]).

use std::f32::consts::PI;
use std::sync::OnceLock;

use super::{Lobe, LocalSample};
use crate::math::{Float, Vec2, Vec3, sin_cos};

/// Below this `alpha` a surface is a mirror: its lobe is a delta, sampled exactly,
/// rather than a distribution whose `D` would overflow.
pub const DELTA_ALPHA: Float = 1e-4;

/// What a microfacet distribution gives: its `D`, Smith's `Lambda`, the visibility in
/// the form its specification writes, and sampling of visible normals; the terms
/// built of these alike for every distribution are provided here once.
pub trait Distribution {
    /// `D(h)` for a unit `h` in the shading frame.
    fn d(&self, h: Vec3) -> Float;

    /// Smith's `Lambda(w)`.
    fn lambda(&self, w: Vec3) -> Float;

    /// The height-correlated visibility `V = G2 / (4 |n.wo| |n.wi|)`.
    fn visibility(&self, wo: Vec3, wi: Vec3) -> Float;

    /// A microfacet normal seen from `wo` (`wo.z > 0`), distributed as
    /// [`Distribution::visible_pdf`].
    fn sample_visible(&self, wo: Vec3, u: Vec2) -> Vec3;

    /// Smith's masking `G1(w) = 1 / (1 + Lambda(w))`.
    #[inline]
    fn g1(&self, w: Vec3) -> Float {
        1.0 / (1.0 + self.lambda(w))
    }

    /// The height-correlated masking-shadowing `G2 = 1 / (1 + Lambda(wo) +
    /// Lambda(wi))`.
    #[inline]
    fn g2(&self, wo: Vec3, wi: Vec3) -> Float {
        1.0 / (1.0 + self.lambda(wo) + self.lambda(wi))
    }

    /// The separable Smith visibility `G1(wo) G1(wi) / (4 |n.wo| |n.wi|)`: Mitsuba 3's
    /// and pbrt-v3's masking-shadowing, for comparing with them (glTF's is
    /// [`Distribution::visibility`]).
    #[inline]
    fn separable_visibility(&self, wo: Vec3, wi: Vec3) -> Float {
        let cosines = 4.0 * wo.z.abs() * wi.z.abs();
        if cosines > 0.0 {
            self.g1(wo) * self.g1(wi) / cosines
        } else {
            0.0
        }
    }

    /// The density of [`Distribution::sample_visible`] at the microfacet normal `h`:
    /// `G1(wo) max(0, wo.h) D(h) / |wo.z|`.
    #[inline]
    fn visible_pdf(&self, wo: Vec3, h: Vec3) -> Float {
        let cos_o = wo.z.abs();
        if cos_o <= 0.0 {
            return 0.0;
        }
        self.g1(wo) * wo.dot(h).max(0.0) * self.d(h) / cos_o
    }
}

/// An isotropic GGX distribution of microfacet normals.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ggx {
    /// `alpha = roughness^2`.
    pub alpha: Float,
}

impl Ggx {
    /// The distribution of perceptual roughness `roughness` (`alpha = roughness^2`).
    #[inline]
    pub fn from_roughness(roughness: Float) -> Ggx {
        Ggx {
            alpha: roughness * roughness,
        }
    }

    /// Whether the surface is smooth enough to be a delta lobe.
    #[inline]
    pub fn is_delta(&self) -> bool {
        self.alpha < DELTA_ALPHA
    }
}

impl Distribution for Ggx {
    /// `D(h)` for a unit `h` in the shading frame.
    #[inline]
    fn d(&self, h: Vec3) -> Float {
        if h.z <= 0.0 {
            return 0.0;
        }
        let a2 = self.alpha * self.alpha;
        let t = h.z * h.z * (a2 - 1.0) + 1.0;
        a2 / (PI * t * t)
    }

    /// Smith's `Lambda(w)`.
    #[inline]
    fn lambda(&self, w: Vec3) -> Float {
        let cos2 = w.z * w.z;
        if cos2 <= 0.0 {
            return Float::INFINITY;
        }
        let a2 = self.alpha * self.alpha;
        let tan2 = ((1.0 - cos2) / cos2).max(0.0);
        0.5 * ((1.0 + a2 * tan2).sqrt() - 1.0)
    }

    /// glTF's visibility `V = G2 / (4 |n.wo| |n.wi|)`, in the form Appendix B writes
    /// it: `0.5 / (|n.wi| sqrt(a^2 + (1 - a^2) (n.wo)^2) + |n.wo| sqrt(a^2 + (1 - a^2)
    /// (n.wi)^2))`, which stays finite at grazing angles.
    #[inline]
    fn visibility(&self, wo: Vec3, wi: Vec3) -> Float {
        let a2 = self.alpha * self.alpha;
        let (co, ci) = (wo.z.abs(), wi.z.abs());
        let denominator =
            ci * (a2 + (1.0 - a2) * co * co).sqrt() + co * (a2 + (1.0 - a2) * ci * ci).sqrt();
        if denominator > 0.0 {
            0.5 / denominator
        } else {
            0.0
        }
    }

    /// A microfacet normal seen from `wo` (`wo.z > 0`), distributed as
    /// [`Ggx::visible_pdf`]: Dupuy and Benyoub's (2023) "Sampling Visible GGX
    /// Normals with Spherical Caps", the same distribution as Heitz's (2018)
    /// construction with one square root and one division fewer (no tangent frame
    /// about the view direction).
    #[inline]
    fn sample_visible(&self, wo: Vec3, u: Vec2) -> Vec3 {
        visible_normal(self.alpha, self.alpha, wo, u)
    }
}

/// An anisotropic GGX distribution (`KHR_materials_anisotropy`): `alpha_x` along
/// the local `x` (the direction of anisotropy, glTF's `alpha_t = mix(alpha, 1,
/// strength^2)`), `alpha_y` along `y` (glTF's `alpha_b = alpha`):
/// `D = 1 / (pi ax ay ((h.x/ax)^2 + (h.y/ay)^2 + h.z^2)^2)`, Smith's `Lambda(w) =
/// (sqrt(1 + (ax^2 w.x^2 + ay^2 w.y^2) / w.z^2) - 1) / 2` and the height-correlated
/// `V = 0.5 / (|n.wi| |(ax wo.x, ay wo.y, wo.z)| + |n.wo| |(ax wi.x, ay wi.y,
/// wi.z)|)`, as the extension's "Implementation" section writes them; visible
/// normals sampled by stretching `wo` to the hemisphere configuration, as pbrt-v4's
/// `TrowbridgeReitzDistribution::Sample_wm` does with its two alphas. With equal
/// alphas it is [`Ggx`] (which stays the isotropic path, bit for bit).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AnisoGgx {
    /// `alpha` along the local `x`.
    pub alpha_x: Float,
    /// `alpha` along the local `y`.
    pub alpha_y: Float,
}

impl AnisoGgx {
    /// glTF's anisotropic distribution of perceptual roughness `roughness` and
    /// anisotropy strength `strength` (in [0, 1]): `alpha_x = mix(alpha, 1,
    /// strength^2)`, `alpha_y = alpha`, `alpha = roughness^2`; both at least
    /// [`MIN_ANISO_ALPHA`], so that a smooth anisotropic surface stays a (very
    /// narrow) distribution rather than a line.
    #[inline]
    pub fn from_roughness(roughness: Float, strength: Float) -> AnisoGgx {
        let alpha = roughness * roughness;
        let s2 = strength * strength;
        AnisoGgx {
            alpha_x: (alpha * (1.0 - s2) + s2).max(MIN_ANISO_ALPHA),
            alpha_y: alpha.max(MIN_ANISO_ALPHA),
        }
    }

    /// `|(ax w.x, ay w.y, w.z)|`: `|w.z| (1 + 2 Lambda(w))`, the half of the
    /// visibility that depends on `w` alone.
    #[inline]
    pub fn stretched_length(&self, w: Vec3) -> Float {
        Vec3::new(self.alpha_x * w.x, self.alpha_y * w.y, w.z).length()
    }
}

impl Distribution for AnisoGgx {
    /// `D(h)` for a unit `h` in the shading frame.
    #[inline]
    fn d(&self, h: Vec3) -> Float {
        if h.z <= 0.0 {
            return 0.0;
        }
        let (x, y) = (h.x / self.alpha_x, h.y / self.alpha_y);
        let s = x * x + y * y + h.z * h.z;
        1.0 / (PI * self.alpha_x * self.alpha_y * s * s)
    }

    /// Smith's `Lambda(w)`.
    #[inline]
    fn lambda(&self, w: Vec3) -> Float {
        let cos2 = w.z * w.z;
        if cos2 <= 0.0 {
            return Float::INFINITY;
        }
        let (x, y) = (self.alpha_x * w.x, self.alpha_y * w.y);
        let tan2 = (x * x + y * y) / cos2;
        0.5 * ((1.0 + tan2).sqrt() - 1.0)
    }

    /// The extension's `V = G2 / (4 |n.wo| |n.wi|)`.
    #[inline]
    fn visibility(&self, wo: Vec3, wi: Vec3) -> Float {
        let denominator =
            wi.z.abs() * self.stretched_length(wo) + wo.z.abs() * self.stretched_length(wi);
        if denominator > 0.0 {
            0.5 / denominator
        } else {
            0.0
        }
    }

    /// A microfacet normal seen from `wo` (`wo.z > 0`), distributed as
    /// [`AnisoGgx::visible_pdf`]: `wo` stretched by the two alphas to the
    /// hemisphere configuration, a visible normal of the unit hemisphere drawn on its
    /// spherical cap as [`Ggx::sample_visible`] does, stretched back.
    #[inline]
    fn sample_visible(&self, wo: Vec3, u: Vec2) -> Vec3 {
        visible_normal(self.alpha_x, self.alpha_y, wo, u)
    }
}

/// A microfacet normal of the GGX distribution of `alpha`s `ax` along the local `x`
/// and `ay` along `y`, seen from `wo` (`wo.z > 0`): `wo` stretched to the hemisphere
/// configuration, a direction drawn uniformly on the spherical cap of the unit sphere
/// below the plane through the origin normal to it (Dupuy and Benyoub 2023), and
/// the normal there stretched back.
#[inline]
fn visible_normal(ax: Float, ay: Float, wo: Vec3, u: Vec2) -> Vec3 {
    // The view direction in the hemisphere configuration.
    let v = Vec3::new(ax * wo.x, ay * wo.y, wo.z).normalize();
    // `z` in `[-v.z, 1]`.
    let z = (1.0 - u.x) * (1.0 + v.z) - v.z;
    let sin_theta = (1.0 - z * z).max(0.0).sqrt();
    let (sin, cos) = sin_cos(2.0 * PI * u.y);
    let h = Vec3::new(sin_theta * cos + v.x, sin_theta * sin + v.y, z + v.z);
    Vec3::new(ax * h.x, ay * h.y, h.z.max(1e-6)).normalize()
}

/// The smallest `alpha` of an anisotropic distribution along either axis.
pub const MIN_ANISO_ALPHA: Float = 1e-3;

/// Cosines of the albedo table, from 0 to 1.
const ALBEDO_COSINES: usize = 32;
/// `alpha`s of the albedo table, from 0 to 1.
const ALBEDO_ALPHAS: usize = 32;

/// The directional albedo `E(cos) = integral D V |n.wi| dwi` of the white reflection
/// lobe ([`GgxReflection`]: no Fresnel) of `alpha`, for `cos = n.wo`: bilinear in a
/// table made once by [`quadrature_albedo`]. What single scattering loses,
/// `1 - E`, is what multiple-scattering compensation puts back.
pub fn albedo(cos: Float, alpha: Float) -> Float {
    static TABLE: OnceLock<Vec<Float>> = OnceLock::new();
    let table = TABLE.get_or_init(|| {
        let mut table = Vec::with_capacity(ALBEDO_COSINES * ALBEDO_ALPHAS);
        for a in 0..ALBEDO_ALPHAS {
            let alpha = (a as Float / (ALBEDO_ALPHAS - 1) as Float).max(DELTA_ALPHA);
            for c in 0..ALBEDO_COSINES {
                let cos = (c as Float / (ALBEDO_COSINES - 1) as Float).max(1e-3);
                table.push(quadrature_albedo(cos, alpha));
            }
        }
        table
    });
    bilinear(table, ALBEDO_COSINES, cos, alpha)
}

/// The value at (`x`, `y`), both in [0, 1] (clamped), of `table`, a grid of
/// `columns` values a row over `[0, 1]^2` (rows along `y`), interpolated bilinearly.
fn bilinear(table: &[Float], columns: usize, x: Float, y: Float) -> Float {
    let rows = table.len() / columns;
    let x = x.clamp(0.0, 1.0) * (columns - 1) as Float;
    let y = y.clamp(0.0, 1.0) * (rows - 1) as Float;
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(columns - 1), (y0 + 1).min(rows - 1));
    let (fx, fy) = (x - x0 as Float, y - y0 as Float);
    let at = |x: usize, y: usize| table[y * columns + x];
    let top = at(x0, y0) + (at(x1, y0) - at(x0, y0)) * fx;
    let bottom = at(x0, y1) + (at(x1, y1) - at(x0, y1)) * fx;
    top + (bottom - top) * fy
}

/// `E(cos)` of [`albedo`] by a stratified quadrature over the visible normals: with
/// `h` drawn from [`Ggx::sample_visible`], `D V |n.wi| / pdf = G2(wo, wi) / G1(wo)`
/// (the pdf cancels all but the masking), averaged over a 48 x 48 grid of midpoints.
pub fn quadrature_albedo(cos: Float, alpha: Float) -> Float {
    let ggx = Ggx { alpha };
    let wo = Vec3::new((1.0 - cos * cos).max(0.0).sqrt(), 0.0, cos);
    let n = 48;
    let g1 = ggx.g1(wo) as f64;
    let mut sum = 0.0f64;
    for i in 0..n {
        for j in 0..n {
            let u = Vec2::new(
                (i as Float + 0.5) / n as Float,
                (j as Float + 0.5) / n as Float,
            );
            let wi = crate::math::reflect(-wo, ggx.sample_visible(wo, u));
            if wi.z > 0.0 {
                sum += ggx.g2(wo, wi) as f64 / g1;
            }
        }
    }
    (sum / (n * n) as f64) as Float
}

/// Cosines and `alpha`s of the split-sum table, each from 0 to 1.
const SPLIT_SUM_SIZE: usize = 16;

/// The directional albedo of the GGX lobe of `alpha` with Schlick's Fresnel term
/// `F = f0 + (f90 - f0) (1 - wo.h)^5`, for `cos = n.wo`, as two weights `(a, b)`:
/// `E = f0 a + f90 b`, `a` being the integral of `(1 - (1 - wo.h)^5) D V |n.wi|` and
/// `b` that of `(1 - wo.h)^5 D V |n.wi|`: the table image-based lighting's split-sum
/// approximation reads (Karis, "Real Shading in Unreal Engine 4", 2013; the Khronos
/// sample viewer's and three.js's), here for glTF's height-correlated masking.
/// Bilinear in a 16 x 16 table made once by [`quadrature_split_sum`] (a few
/// milliseconds: only full mode's studio reflections read it).
pub fn split_sum(cos: Float, alpha: Float) -> (Float, Float) {
    static TABLES: OnceLock<[Vec<Float>; 2]> = OnceLock::new();
    let [a, b] = TABLES.get_or_init(|| {
        let mut tables = [Vec::new(), Vec::new()];
        for row in 0..SPLIT_SUM_SIZE {
            let alpha = (row as Float / (SPLIT_SUM_SIZE - 1) as Float).max(DELTA_ALPHA);
            for column in 0..SPLIT_SUM_SIZE {
                let cos = (column as Float / (SPLIT_SUM_SIZE - 1) as Float).max(1e-3);
                let (a, b) = quadrature_split_sum(cos, alpha, 24);
                tables[0].push(a);
                tables[1].push(b);
            }
        }
        tables
    });
    (
        bilinear(a, SPLIT_SUM_SIZE, cos, alpha),
        bilinear(b, SPLIT_SUM_SIZE, cos, alpha),
    )
}

/// [`split_sum`]'s two weights by the quadrature of [`quadrature_albedo`] over an
/// `n x n` grid, each sample's `G2 / G1` split by its Fresnel weight `(1 - wo.h)^5`.
pub fn quadrature_split_sum(cos: Float, alpha: Float, n: usize) -> (Float, Float) {
    let ggx = Ggx { alpha };
    let wo = Vec3::new((1.0 - cos * cos).max(0.0).sqrt(), 0.0, cos);
    let g1 = ggx.g1(wo) as f64;
    let (mut a, mut b) = (0.0f64, 0.0f64);
    for i in 0..n {
        for j in 0..n {
            let u = Vec2::new(
                (i as Float + 0.5) / n as Float,
                (j as Float + 0.5) / n as Float,
            );
            let h = ggx.sample_visible(wo, u);
            let wi = crate::math::reflect(-wo, h);
            if wi.z > 0.0 {
                let weight = ggx.g2(wo, wi) as f64 / g1;
                let fresnel = f64::from((1.0 - wo.dot(h)).clamp(0.0, 1.0)).powi(5);
                a += weight * (1.0 - fresnel);
                b += weight * fresnel;
            }
        }
    }
    let samples = (n * n) as f64;
    ((a / samples) as Float, (b / samples) as Float)
}

/// Turquin's (2019) multiple-scattering compensation of a GGX lobe whose
/// single-scattering directional albedo (white) at `wo` is `e`: the lobe times
/// `1 + f0 (1 - e) / e`, so that a white conductor (`f0` 1) reflects all it
/// receives, at any roughness; `f0` tints what the extra bounces add.
#[inline]
pub fn compensation(f0: Vec3, e: Float) -> Vec3 {
    let e = e.max(1e-3);
    Vec3::ONE + f0 * ((1.0 - e) / e)
}

/// The reflection lobe `D V` of a GGX surface (white, no Fresnel), isotropic
/// ([`Ggx`]) or anisotropic ([`AnisoGgx`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GgxReflection<D = Ggx> {
    /// The distribution.
    pub ggx: D,
}

/// The reflection lobe of an anisotropic GGX surface.
pub type AnisoGgxReflection = GgxReflection<AnisoGgx>;

impl<D: Distribution> Lobe for GgxReflection<D> {
    #[inline]
    fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        let h = (wo + wi).normalize();
        Vec3::splat(self.ggx.d(h) * self.ggx.visibility(wo, wi))
    }

    #[inline]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> Float {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let h = (wo + wi).normalize();
        reflection_pdf(&self.ggx, wo, h)
    }

    #[inline]
    fn sample(&self, wo: Vec3, _u_lobe: Float, u: Vec2) -> Option<LocalSample> {
        if wo.z <= 0.0 {
            return None;
        }
        let h = self.ggx.sample_visible(wo, u);
        let wi = crate::math::reflect(-wo, h);
        let pdf = self.pdf(wo, wi);
        (pdf > 0.0).then(|| LocalSample::smooth(wi, self.eval(wo, wi) * wi.z / pdf, pdf))
    }
}

/// The density of the reflected direction whose half vector is `h`, when `h` is
/// sampled from the normals visible from `wo`: `visible_pdf / (4 wo.h)`.
#[inline]
pub fn reflection_pdf(ggx: &impl Distribution, wo: Vec3, h: Vec3) -> Float {
    let cos = wo.dot(h);
    if cos <= 0.0 {
        return 0.0;
    }
    ggx.visible_pdf(wo, h) / (4.0 * cos)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The integral of `f(wi) |n.wi|` over the hemisphere by an `n_t x n_phi`
    /// midpoint grid uniform in `cos^2` and azimuth: the cosine-weighted measure,
    /// total pi.
    fn cosine_weighted_quadrature(n_t: usize, n_phi: usize, mut f: impl FnMut(Vec3) -> f64) -> f64 {
        let mut sum = 0.0f64;
        for i in 0..n_t {
            let t = (i as Float + 0.5) / n_t as Float;
            let (z, r) = (t.sqrt(), (1.0 - t).sqrt());
            for j in 0..n_phi {
                let phi = 2.0 * PI * (j as Float + 0.5) / n_phi as Float;
                sum += f(Vec3::new(r * phi.cos(), r * phi.sin(), z));
            }
        }
        sum * std::f64::consts::PI / (n_t * n_phi) as f64
    }

    /// The albedo table agrees with a midpoint quadrature of `D V cos` over the
    /// hemisphere (the lobe's `eval`, not its sampling), between its nodes too.
    #[test]
    fn the_albedo_table_is_the_lobes_directional_albedo() {
        let mut worst: (f64, Float, Float) = (0.0, 0.0, 0.0);
        for alpha in [0.1, 0.27, 0.5, 0.81, 1.0] {
            let lobe = GgxReflection { ggx: Ggx { alpha } };
            for cos in [0.15 as Float, 0.33, 0.7, 1.0] {
                let wo = Vec3::new((1.0 - cos * cos).sqrt(), 0.0, cos);
                let quadrature =
                    cosine_weighted_quadrature(600, 300, |wi| lobe.eval(wo, wi).x as f64);
                let error = (albedo(cos, alpha) as f64 - quadrature).abs();
                if error > worst.0 {
                    worst = (error, alpha, cos);
                }
            }
        }
        assert!(
            worst.0 < 0.01,
            "error {} at alpha {}, cos {}",
            worst.0,
            worst.1,
            worst.2
        );
    }

    /// The split-sum table's two weights agree with a midpoint quadrature of the
    /// lobe's `eval` over the hemisphere, split by Schlick's Fresnel weight
    /// `(1 - wo.h)^5`, between its nodes too (to 0.015 and 0.01: the table is
    /// coarse, 16 x 16, where sharp lobes change fast near grazing); a mirror's are
    /// Schlick's at the view angle, `1 - (1 - cos)^5` and `(1 - cos)^5`.
    #[test]
    fn the_split_sum_table_is_the_fresnel_weighted_albedo() {
        for alpha in [0.09, 0.3, 0.55, 1.0] {
            let lobe = GgxReflection { ggx: Ggx { alpha } };
            for cos in [0.2 as Float, 0.45, 0.8, 1.0] {
                let wo = Vec3::new((1.0 - cos * cos).sqrt(), 0.0, cos);
                // The lobe weighted by Schlick's term at its half vector, or by the rest.
                let weighted = |schlick: bool| {
                    cosine_weighted_quadrature(400, 200, |wi| {
                        let fresnel = f64::from(1.0 - wo.dot((wo + wi).normalize())).powi(5);
                        let weight = if schlick { fresnel } else { 1.0 - fresnel };
                        lobe.eval(wo, wi).x as f64 * weight
                    })
                };
                let (a, b) = (weighted(false), weighted(true));
                let (ta, tb) = split_sum(cos, alpha);
                assert!(
                    (ta as f64 - a).abs() < 0.015 && (tb as f64 - b).abs() < 0.01,
                    "alpha {alpha}, cos {cos}: table ({ta}, {tb}), quadrature ({a}, {b})"
                );
            }
        }
        // At the table's cosines (multiples of 1/15): between them, the
        // interpolation of the curved `(1 - cos)^5` is off by up to 0.01.
        for cos in [0.2 as Float, 0.6, 1.0] {
            let (a, b) = split_sum(cos, 0.0);
            let schlick = (1.0 - cos).powi(5);
            assert!((a - (1.0 - schlick)).abs() < 1e-3 && (b - schlick).abs() < 1e-3);
        }
    }

    /// `D` is normalized: the projected area of the microfacets is the macro
    /// surface's, `integral D(h) (n.h) dh = 1`, by a midpoint quadrature.
    #[test]
    fn projected_microfacet_area_is_one() {
        for alpha in [0.05, 0.3, 0.8, 1.0] {
            let ggx = Ggx { alpha };
            let n = 4000;
            let mut sum = 0.0f64;
            for i in 0..n {
                // Substituting cos^2 makes the narrow lobes resolvable.
                let t = (i as f64 + 0.5) / n as f64;
                let cos = t.sqrt();
                let h = Vec3::new((1.0 - t).sqrt() as Float, 0.0, cos as Float);
                // dw = 2 pi sin dtheta = pi d(cos^2) / cos.
                sum += ggx.d(h) as f64 * cos * std::f64::consts::PI / cos / n as f64;
            }
            assert!((sum - 1.0).abs() < 2e-3, "alpha {alpha}: {sum}");
        }
    }
}
