//! The sheen lobe of `KHR_materials_sheen`: the "Charlie" distribution of Estevez
//! and Kulla (2017), `D = (2 + 1/alpha) sin(theta_h)^(1/alpha) / (2 pi)` with
//! `alpha = sheenRoughness^2`, and their fitted visibility, as the extension defines
//! them. It is sampled by the cosine (the lobe is broad). [`albedo`] is its
//! directional albedo, by which glTF scales the material under it down
//! ("albedo scaling").

use std::f32::consts::PI;
use std::sync::OnceLock;

use super::lambert::{cosine_on_the_side_of, cosine_pdf};
use super::{Lobe, LocalSample, same_hemisphere};
use crate::math::{Float, Vec2, Vec3};

/// The smallest sheen roughness used: three.js and the Khronos sample viewer clamp
/// it too, since the distribution degenerates to a spike at grazing angles.
const MIN_ROUGHNESS: Float = 0.07;

/// A sheen lobe of colour `color` and perceptual roughness `roughness`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sheen {
    /// `sheenColor`.
    pub color: Vec3,
    /// `alpha = max(sheenRoughness, 0.07)^2`.
    pub alpha: Float,
}

impl Sheen {
    /// The lobe of `color` and perceptual `roughness`.
    pub fn new(color: Vec3, roughness: Float) -> Sheen {
        let r = roughness.max(MIN_ROUGHNESS);
        Sheen {
            color,
            alpha: r * r,
        }
    }

    /// `D(h)`.
    #[inline]
    pub fn d(&self, h: Vec3) -> Float {
        let inverse = 1.0 / self.alpha;
        let sin2 = (1.0 - h.z * h.z).max(0.0);
        (2.0 + inverse) * sin2.powf(0.5 * inverse) / (2.0 * PI)
    }

    /// The extension's visibility, `1 / ((1 + Lambda(wo) + Lambda(wi)) 4 |n.wo|
    /// |n.wi|)`.
    #[inline]
    pub fn visibility(&self, wo: Vec3, wi: Vec3) -> Float {
        let (co, ci) = (wo.z.abs(), wi.z.abs());
        let denominator = (1.0 + lambda(co, self.alpha) + lambda(ci, self.alpha)) * 4.0 * co * ci;
        if denominator > 0.0 {
            1.0 / denominator
        } else {
            0.0
        }
    }

    /// The lobe's value for white sheen, `D V`.
    #[inline]
    pub fn white(&self, wo: Vec3, wi: Vec3) -> Float {
        let h = (wo + wi).normalize();
        self.d(h) * self.visibility(wo, wi)
    }
}

/// The fitted curve of the extension's `Lambda`.
fn curve(x: Float, alpha: Float) -> Float {
    let t = (1.0 - alpha) * (1.0 - alpha);
    let mix = |a: Float, b: Float| a + (b - a) * t;
    let a = mix(21.5473, 25.3245);
    let b = mix(3.82987, 3.32435);
    let c = mix(0.19823, 0.16801);
    let d = mix(-1.97760, -1.27393);
    let e = mix(-4.32054, -4.85967);
    a / (1.0 + b * x.powf(c)) + d * x + e
}

fn lambda(cos: Float, alpha: Float) -> Float {
    if cos < 0.5 {
        curve(cos, alpha).exp()
    } else {
        (2.0 * curve(0.5, alpha) - curve(1.0 - cos, alpha)).exp()
    }
}

impl Lobe for Sheen {
    #[inline]
    fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if !same_hemisphere(wo, wi) || wo.z == 0.0 {
            return Vec3::ZERO;
        }
        self.color * self.white(wo, wi)
    }

    #[inline]
    fn pdf(&self, wo: Vec3, wi: Vec3) -> Float {
        cosine_pdf(wo, wi)
    }

    #[inline]
    fn sample(&self, wo: Vec3, _u_lobe: Float, u: Vec2) -> Option<LocalSample> {
        let wi = cosine_on_the_side_of(wo, u);
        let pdf = cosine_pdf(wo, wi);
        (pdf > 0.0).then(|| LocalSample::smooth(wi, self.eval(wo, wi) * wi.z.abs() / pdf, pdf))
    }
}

const ALBEDO_COSINES: usize = 32;
const ALBEDO_ROUGHNESSES: usize = 16;

/// The directional albedo of white sheen, `E(cos) = integral D V |n.wi| dwi`, for
/// perceptual `roughness` and `cos = |n.wo|`: bilinear in a table made once by
/// quadrature.
pub fn albedo(cos: Float, roughness: Float) -> Float {
    static TABLE: OnceLock<Vec<Float>> = OnceLock::new();
    let table = TABLE.get_or_init(|| {
        let mut table = Vec::with_capacity(ALBEDO_COSINES * ALBEDO_ROUGHNESSES);
        for r in 0..ALBEDO_ROUGHNESSES {
            let roughness = r as Float / (ALBEDO_ROUGHNESSES - 1) as Float;
            for c in 0..ALBEDO_COSINES {
                let cos = (c as Float / (ALBEDO_COSINES - 1) as Float).max(1e-3);
                table.push(quadrature_albedo(cos, roughness));
            }
        }
        table
    });
    let x = cos.clamp(0.0, 1.0) * (ALBEDO_COSINES - 1) as Float;
    let y = roughness.clamp(0.0, 1.0) * (ALBEDO_ROUGHNESSES - 1) as Float;
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = (
        (x0 + 1).min(ALBEDO_COSINES - 1),
        (y0 + 1).min(ALBEDO_ROUGHNESSES - 1),
    );
    let (fx, fy) = (x - x0 as Float, y - y0 as Float);
    let at = |x: usize, y: usize| table[y * ALBEDO_COSINES + x];
    let top = at(x0, y0) + (at(x1, y0) - at(x0, y0)) * fx;
    let bottom = at(x0, y1) + (at(x1, y1) - at(x0, y1)) * fx;
    top + (bottom - top) * fy
}

/// `E(cos)` by a midpoint quadrature over the hemisphere, in `cos^2` and azimuth.
pub fn quadrature_albedo(cos: Float, roughness: Float) -> Float {
    let sheen = Sheen::new(Vec3::ONE, roughness);
    let wo = Vec3::new((1.0 - cos * cos).max(0.0).sqrt(), 0.0, cos);
    let (n_theta, n_phi) = (64, 64);
    let mut sum = 0.0f64;
    for i in 0..n_theta {
        // Uniform in cos^2: dw |cos| = pi d(cos^2) / (2 pi) dphi... i.e. the
        // cosine-weighted measure, of total pi.
        let t = (i as Float + 0.5) / n_theta as Float;
        let z = t.sqrt();
        let s = (1.0 - t).max(0.0).sqrt();
        for j in 0..n_phi {
            let phi = PI * (j as Float + 0.5) / n_phi as Float;
            let wi = Vec3::new(s * phi.cos(), s * phi.sin(), z);
            // The lobe is symmetric in phi: half the circle, counted twice.
            sum += sheen.white(wo, wi) as f64;
        }
    }
    (sum * std::f64::consts::PI / (n_theta * n_phi) as f64) as Float
}
