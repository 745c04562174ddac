//! What surfaces scatter in path mode, as pbrt-v4's `bxdfs` and Mitsuba 3's
//! `src/bsdfs/` split it: one lobe per file, each a [`Lobe`] in the local shading
//! frame ([`Frame`]: `z` the shading normal), and the two materials made of them, as
//! the closed enum [`Bsdf`]:
//!
//! - [`mtl::MtlMixture`]: SPEC's MTL material in path mode, a mixture of
//!   [`lambert`], [`phong`], a mirror and smooth glass weighted by `al`;
//! - [`gltf::GltfBsdf`]: glTF's metallic-roughness model with its extensions, of
//!   [`lambert`], [`microfacet`] (GGX reflection and transmission), [`sheen`] and
//!   [`fresnel`].
//!
//! Directions follow pbrt's convention: `wo` points away from the surface towards
//! where the path came from, `wi` towards where it goes next. The shading normal
//! faces `wo` (hits are flipped to face the ray). A new lobe is a file here with a
//! [`Lobe`] impl (and its line in the conformance suite); a new material model is a
//! [`Bsdf`] variant.

pub mod fresnel;
pub mod gltf;
pub mod lambert;
pub mod microfacet;
pub mod mtl;
pub mod phong;
pub mod sheen;

#[cfg(test)]
mod conformance;

use crate::math::{Float, Vec2, Vec3};

/// An orthonormal shading frame: `n` the shading normal, `t` and `b` tangents.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// First tangent.
    pub t: Vec3,
    /// Second tangent, `n x t`.
    pub b: Vec3,
    /// The unit normal.
    pub n: Vec3,
}

impl Frame {
    /// A frame about the unit normal `n`, its tangents from the branchless basis of
    /// Duff et al. (2017) (isotropic lobes do not care which).
    #[inline]
    pub fn from_normal(n: Vec3) -> Frame {
        let sign = 1.0_f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        Frame {
            t: Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
            b: Vec3::new(b, sign + n.y * n.y * a, -n.y),
            n,
        }
    }

    /// `v` in the frame's coordinates.
    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.t), v.dot(self.b), v.dot(self.n))
    }

    /// `v` given in the frame's coordinates, in the world's.
    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        v.x * self.t + v.y * self.b + v.z * self.n
    }
}

/// Whether `wo` and `wi` lie on the same side of the local surface.
#[inline]
pub fn same_hemisphere(wo: Vec3, wi: Vec3) -> bool {
    wo.z * wi.z > 0.0
}

/// A direction a lobe sampled, in its local frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LocalSample {
    /// Unit direction.
    pub wi: Vec3,
    /// `f |cos| / pdf`.
    pub weight: Vec3,
    /// Density (solid angle); for a delta lobe, the probability of choosing it.
    pub pdf: Float,
    /// Whether the direction came from a delta lobe (a mirror, smooth glass).
    pub delta: bool,
    /// Relative index of refraction crossed (index entered over index left; 1 for
    /// reflection).
    pub eta: Float,
}

impl LocalSample {
    /// A reflected sample of a non-delta lobe.
    #[inline]
    pub fn smooth(wi: Vec3, weight: Vec3, pdf: Float) -> LocalSample {
        LocalSample {
            wi,
            weight,
            pdf,
            delta: false,
            eta: 1.0,
        }
    }
}

/// One lobe in its local frame: what the conformance suite checks every lobe for
/// (sampling against `pdf`, `pdf` against `eval`, reciprocity, energy). Static
/// dispatch only: materials hold lobes by value.
pub trait Lobe {
    /// `f(wo, wi)`, delta lobes excluded.
    fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3;
    /// The density with which `sample` picks `wi` through non-delta lobes.
    fn pdf(&self, wo: Vec3, wi: Vec3) -> Float;
    /// A direction: `u_lobe` picks a lobe where there are several, `u` a direction.
    fn sample(&self, wo: Vec3, u_lobe: Float, u: Vec2) -> Option<LocalSample>;
}

/// A direction chosen by [`Bsdf::sample`], in world space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ScatterSample {
    /// Unit direction the path continues in.
    pub wi: Vec3,
    /// `f * |cos| / pdf`: what the path throughput is multiplied by.
    pub weight: Vec3,
    /// Probability density of `wi` (solid angle) over the non-delta lobes, for
    /// multiple importance sampling; meaningless when `delta`.
    pub pdf: Float,
    /// A delta lobe was chosen: no light sampling strategy could have found `wi`.
    pub delta: bool,
    /// The relative index of refraction crossed (1 for reflection), for Russian
    /// roulette (as Mitsuba's `eta`).
    pub eta: Float,
}

/// The scattering at one point: a closed set of material models.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Bsdf {
    /// SPEC's MTL material.
    Mtl(mtl::MtlMixture),
    /// glTF's metallic-roughness material.
    Gltf(gltf::GltfBsdf),
}

impl Bsdf {
    /// Whether some lobe is not a delta, so that light sampling can reach it.
    #[inline]
    pub fn has_smooth_lobes(&self) -> bool {
        match self {
            Bsdf::Mtl(m) => m.has_smooth_lobes(),
            Bsdf::Gltf(g) => g.has_smooth_lobes(),
        }
    }

    /// `f(wo, wi)` of the non-delta lobes. `ns` is the unit shading normal facing
    /// `wo`, `ng` the geometric one (also facing `wo`); `front` says whether `wo` is
    /// on the side the geometric normal of the surface faces (outside a volume).
    #[inline(always)]
    pub fn eval(&self, wo: Vec3, wi: Vec3, ns: Vec3, ng: Vec3, front: bool) -> Vec3 {
        match self {
            Bsdf::Mtl(m) => m.eval(wo, wi, ns, ng),
            Bsdf::Gltf(g) => gltf_eval(g, wo, wi, ns, ng, front),
        }
    }

    /// The density (solid angle) with which [`Bsdf::sample`] picks `wi` through its
    /// non-delta lobes (arguments as [`Bsdf::eval`]'s).
    #[inline(always)]
    pub fn pdf(&self, wo: Vec3, wi: Vec3, ns: Vec3, ng: Vec3, front: bool) -> Float {
        match self {
            Bsdf::Mtl(m) => m.pdf(wo, wi, ns, ng),
            Bsdf::Gltf(g) => gltf_pdf(g, wo, wi, ns, ng, front),
        }
    }

    /// Picks the direction the path continues in: a lobe by `u_lobe`, a direction in
    /// it by `u`. `front` says whether the ray hit the side the surface's geometric
    /// normal faces, which tells entering glass from leaving it. `None` when the
    /// material scatters nothing that way.
    #[inline(always)]
    pub fn sample(
        &self,
        wo: Vec3,
        ns: Vec3,
        ng: Vec3,
        front: bool,
        u_lobe: Float,
        u: Vec2,
    ) -> Option<ScatterSample> {
        match self {
            Bsdf::Mtl(m) => m.sample(wo, ns, ng, front, u_lobe, u),
            Bsdf::Gltf(g) => gltf_sample(g, wo, ns, ng, front, u_lobe, u),
        }
    }

    /// The attenuation coefficient of the volume a path enters when it is
    /// transmitted through this surface from its front (`KHR_materials_volume`);
    /// zero for thin surfaces and MTL materials.
    #[inline]
    pub fn attenuation(&self) -> Option<Vec3> {
        match self {
            Bsdf::Mtl(_) => None,
            Bsdf::Gltf(g) => g.attenuation(),
        }
    }
}

// The glTF material's calls in world space, out of line: the MTL material's are
// inlined into the path tracer's loop, which they keep small (a Lambertian scene
// renders as fast as before the glTF BSDF existed).

#[inline(never)]
fn gltf_eval(g: &gltf::GltfBsdf, wo: Vec3, wi: Vec3, ns: Vec3, ng: Vec3, front: bool) -> Vec3 {
    if !agrees(wi, ns, ng) {
        return Vec3::ZERO;
    }
    let frame = Frame::from_normal(ns);
    g.eval_sided(frame.to_local(wo), frame.to_local(wi), front)
}

#[inline(never)]
fn gltf_pdf(g: &gltf::GltfBsdf, wo: Vec3, wi: Vec3, ns: Vec3, ng: Vec3, front: bool) -> Float {
    if !agrees(wi, ns, ng) {
        return 0.0;
    }
    let frame = Frame::from_normal(ns);
    g.pdf_sided(frame.to_local(wo), frame.to_local(wi), front)
}

#[inline(never)]
fn gltf_sample(
    g: &gltf::GltfBsdf,
    wo: Vec3,
    ns: Vec3,
    ng: Vec3,
    front: bool,
    u_lobe: Float,
    u: Vec2,
) -> Option<ScatterSample> {
    let frame = Frame::from_normal(ns);
    let s = g.sample(frame.to_local(wo), front, u_lobe, u)?;
    let wi = frame.to_world(s.wi);
    // Both normals must agree on the side `wi` leaves to, or light would leak
    // through the surface where the shading normal bends away.
    if !s.delta && !agrees(wi, ns, ng) {
        return None;
    }
    Some(ScatterSample {
        wi,
        weight: s.weight,
        pdf: s.pdf,
        delta: s.delta,
        eta: s.eta,
    })
}

/// Whether `wi` lies on the same side of the shading and the geometric surface.
#[inline]
fn agrees(wi: Vec3, ns: Vec3, ng: Vec3) -> bool {
    (wi.dot(ns) > 0.0) == (wi.dot(ng) > 0.0)
}
