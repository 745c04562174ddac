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
pub mod gltf_lanes;
pub mod lambert;
pub mod microfacet;
pub mod mtl;
pub mod phong;
pub mod sheen;

#[cfg(test)]
mod conformance;

use crate::material::{Material, SurfaceValues};
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

    /// The frame of an anisotropic surface about the unit normal `n`, its first
    /// tangent along the direction of anisotropy: `tangent` made orthogonal to `n`
    /// (the hit's, already turned by the material: [`crate::scene::Hit::tangent`]),
    /// or where that is zero or along `n`, a default tangent turned by `direction`
    /// (`(cos, sin)` towards `n x tangent`). The default runs round the up axis,
    /// `+Y x n` (as Blender's radial default round its up axis): continuous over the
    /// whole surface but at the two poles, where [`Frame::from_normal`]'s stands in
    /// (whose own tangent flips where `n.z` changes sign, a seam across a sphere).
    #[inline]
    pub fn anisotropic(n: Vec3, tangent: Vec3, direction: Vec2) -> Frame {
        let t = match (tangent - n * n.dot(tangent)).try_normalize() {
            Some(t) => t,
            None => {
                let radial = match Vec3::Y.cross(n).try_normalize() {
                    Some(t) => t,
                    None => Frame::from_normal(n).t,
                };
                (radial * direction.x + n.cross(radial) * direction.y).normalize()
            }
        };
        Frame {
            t,
            b: n.cross(t),
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

/// The unit shading normal `ns` a path vertex scatters about, seen from `wo`, on a
/// surface of unit geometric normal `ng` (`wo.ng >= 0`): `ns` itself where `wo` is
/// above it and the mirror image of `wo` about it leaves above the surface; else
/// the normal, bent towards `wo`, that mirrors `wo` into a direction `threshold`
/// above the surface (in cosine), `threshold = min(0.9 wo.ng, 0.01)` as Cycles'
/// `ensure_valid_specular_reflection` takes it.
///
/// Interpolated vertex normals face away from the eye along a low-poly silhouette,
/// and normal maps tilt the normal away from grazing views: about such a normal
/// every lobe sees `wo` from below and scatters nothing, and most of what it would
/// reflect leaves through the surface, where `agrees` drops it: black fringes
/// round smooth-shaded models and black specks in normal-mapped ones (Mitsuba 3
/// and pbrt-v4 show them too; Cycles and the raster viewers do not). Flat surfaces
/// (`ns == ng`) are never bent.
#[inline(always)]
pub fn scattering_normal(wo: Vec3, ns: Vec3, ng: Vec3) -> Vec3 {
    if ns == ng {
        return ns;
    }
    let cos_o = wo.dot(ns);
    let mirrored = 2.0 * cos_o * ns - wo;
    let threshold = (0.9 * wo.dot(ng)).min(0.01);
    if cos_o > 0.0 && mirrored.dot(ng) >= threshold {
        return ns;
    }
    bend_towards(wo, mirrored, ng, threshold)
}

/// [`scattering_normal`]'s bent normal: the half vector of `wo` and the direction
/// `threshold` above the surface in the plane of `ng` and `mirrored`.
#[cold]
#[inline(never)]
fn bend_towards(wo: Vec3, mirrored: Vec3, ng: Vec3, threshold: Float) -> Vec3 {
    let along = mirrored - ng * mirrored.dot(ng);
    // Straight down, `mirrored` has no side: away from `wo`, as a grazing view
    // reflects forwards.
    let side = along
        .try_normalize()
        .or_else(|| (ng * wo.dot(ng) - wo).try_normalize())
        .unwrap_or(Vec3::ZERO);
    let wanted = ng * threshold + side * (1.0 - threshold * threshold).max(0.0).sqrt();
    (wo + wanted).try_normalize().unwrap_or(ng)
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
    /// The scattering of the MTL `material` (one with no physically based
    /// statements), at a textured point whose values are `surface` or from its
    /// constants: SPEC's mixture, or a rough dielectric where an `Ns` of 0 or 1 says so
    /// ([`mtl::reads_as_rough_dielectric`]).
    pub fn of_mtl(material: &Material, surface: Option<&SurfaceValues>) -> Bsdf {
        if mtl::reads_as_rough_dielectric(material) {
            let (kd, ks) = surface.map_or((material.diffuse, material.specular), |s| {
                (s.diffuse, s.specular)
            });
            return Bsdf::Gltf(gltf::GltfBsdf::new(&mtl::rough_dielectric(
                kd,
                ks,
                material.shininess,
            )));
        }
        Bsdf::Mtl(match surface {
            Some(surface) => mtl::MtlMixture::at(material, surface),
            None => mtl::MtlMixture::new(material).0,
        })
    }

    /// Whether some lobe is not a delta, so that light sampling can reach it.
    #[inline]
    pub fn has_smooth_lobes(&self) -> bool {
        match self {
            Bsdf::Mtl(m) => m.has_smooth_lobes(),
            Bsdf::Gltf(g) => g.has_smooth_lobes(),
        }
    }

    /// This BSDF at one path vertex, seen from `wo`: `ns` is the unit shading normal
    /// facing `wo`, `ng` the geometric one (also facing `wo`), `coat_ns` a clear
    /// coat's own shading normal ([`crate::scene::Hit::coat_ns`], zero for `ns`),
    /// `tangent` the direction of anisotropy ([`crate::scene::Hit::tangent`], zero
    /// where the hit has none), read by anisotropic materials alone; `front` says
    /// whether `wo` is on the side the geometric normal of the surface faces (outside
    /// a volume). Light sampling's `eval` and `pdf` and the bounce's `sample` share
    /// what it computes once (the frame, the lobe probabilities).
    #[inline(always)]
    pub fn at(
        &self,
        wo: Vec3,
        ns: Vec3,
        ng: Vec3,
        coat_ns: Vec3,
        tangent: Vec3,
        front: bool,
    ) -> BsdfAt<'_> {
        match self {
            Bsdf::Mtl(mixture) => BsdfAt::Mtl {
                mixture,
                wo,
                ns,
                ng,
                front,
            },
            Bsdf::Gltf(g) => gltf_at(g, wo, ns, ng, coat_ns, tangent, front),
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

/// A [`Bsdf`] at one path vertex, seen from one direction ([`Bsdf::at`]).
#[derive(Clone, Copy, Debug)]
pub enum BsdfAt<'a> {
    /// SPEC's MTL material, with the vertex's directions.
    Mtl {
        /// The material.
        mixture: &'a mtl::MtlMixture,
        /// Towards where the path came from.
        wo: Vec3,
        /// Unit shading normal facing `wo`.
        ns: Vec3,
        /// Unit geometric normal facing `wo`.
        ng: Vec3,
        /// Whether `wo` is on the geometric normal's side of the surface.
        front: bool,
    },
    /// glTF's material in its local shading frame.
    Gltf(GltfVertex<'a>),
}

/// The glTF material at a vertex: its local view and the frame to it.
#[derive(Clone, Copy, Debug)]
pub struct GltfVertex<'a> {
    at: gltf::GltfAt<'a>,
    frame: Frame,
    ng: Vec3,
}

impl BsdfAt<'_> {
    /// Whether some lobe seen from `wo` is not a delta, so that light sampling can
    /// reach it.
    #[inline(always)]
    pub fn has_smooth_lobes(&self) -> bool {
        match self {
            BsdfAt::Mtl { mixture, .. } => mixture.has_smooth_lobes(),
            BsdfAt::Gltf(g) => g.at.has_smooth_lobes(),
        }
    }

    /// Whether [`BsdfAt::sample`] reads its `u_lobe`: not for an MTL material of one
    /// lobe ([`mtl::MtlMixture::picks_lobe`]), whose caller may skip drawing it.
    #[inline(always)]
    pub fn picks_lobe(&self) -> bool {
        match self {
            BsdfAt::Mtl { mixture, .. } => mixture.picks_lobe(),
            BsdfAt::Gltf(_) => true,
        }
    }

    /// `f(wo, wi)` of the non-delta lobes.
    #[inline(always)]
    pub fn eval(&self, wi: Vec3) -> Vec3 {
        match self {
            BsdfAt::Mtl {
                mixture,
                wo,
                ns,
                ng,
                ..
            } => mixture.eval(*wo, wi, *ns, *ng),
            BsdfAt::Gltf(g) => gltf_eval(g, wi),
        }
    }

    /// `f(wo, wi)` of the non-delta lobes for a `wi` above the shading surface but
    /// below the geometric one (past a smooth mesh's flat triangle, towards a light
    /// whose shadow ray starts from the smooth surface, [`crate::scene::Hit::lift`]),
    /// where [`BsdfAt::eval`] gives zero lest light leak through the surface. No
    /// scattered ray leaves that way ([`BsdfAt::sample`] drops such directions), so
    /// light sampling alone reaches it, with a weight of 1.
    #[inline(always)]
    pub fn eval_past_terminator(&self, wi: Vec3) -> Vec3 {
        match self {
            BsdfAt::Mtl {
                mixture, wo, ns, ..
            } => mixture.eval(*wo, wi, *ns, *ns),
            BsdfAt::Gltf(g) => gltf_eval_past_terminator(g, wi),
        }
    }

    /// [`BsdfAt::eval`] and, where that is not zero, [`BsdfAt::pdf`] (else 0): a
    /// glTF material computes both from one half vector, as light sampling's MIS
    /// needs them.
    #[inline(always)]
    pub fn eval_and_pdf(&self, wi: Vec3) -> (Vec3, Float) {
        match self {
            BsdfAt::Mtl { .. } => {
                let f = self.eval(wi);
                (f, if f != Vec3::ZERO { self.pdf(wi) } else { 0.0 })
            }
            BsdfAt::Gltf(g) => gltf_eval_pdf(g, wi),
        }
    }

    /// The density (solid angle) with which [`BsdfAt::sample`] picks `wi` through its
    /// non-delta lobes.
    #[inline(always)]
    pub fn pdf(&self, wi: Vec3) -> Float {
        match self {
            BsdfAt::Mtl {
                mixture,
                wo,
                ns,
                ng,
                ..
            } => mixture.pdf(*wo, wi, *ns, *ng),
            BsdfAt::Gltf(g) => gltf_pdf(g, wi),
        }
    }

    /// Picks the direction the path continues in: a lobe by `u_lobe`, a direction in
    /// it by `u`. `None` when the material scatters nothing that way.
    #[inline(always)]
    pub fn sample(&self, u_lobe: Float, u: Vec2) -> Option<ScatterSample> {
        match self {
            BsdfAt::Mtl {
                mixture,
                wo,
                ns,
                ng,
                front,
            } => mixture.sample(*wo, *ns, *ng, *front, u_lobe, u),
            BsdfAt::Gltf(g) => gltf_sample(g, u_lobe, u),
        }
    }
}

// The glTF material's calls in world space, out of line: the MTL material's are
// inlined into the path tracer's loop, which they keep small (a Lambertian scene
// renders as fast as before the glTF BSDF existed). `gltf_at` returns the whole
// `BsdfAt`, made in the caller's place, not a `GltfVertex` that the caller would
// copy into one (a copy that cost the path loop a tenth of its time).

#[inline(never)]
fn gltf_at<'a>(
    g: &'a gltf::GltfBsdf,
    wo: Vec3,
    ns: Vec3,
    ng: Vec3,
    coat_ns: Vec3,
    tangent: Vec3,
    front: bool,
) -> BsdfAt<'a> {
    let frame = match g.anisotropy_direction() {
        None => Frame::from_normal(ns),
        Some(direction) => Frame::anisotropic(ns, tangent, direction),
    };
    let coat = (coat_ns != Vec3::ZERO).then(|| frame.to_local(coat_ns));
    BsdfAt::Gltf(GltfVertex {
        at: g.at(frame.to_local(wo), front, coat),
        frame,
        ng,
    })
}

#[inline(never)]
fn gltf_eval(g: &GltfVertex<'_>, wi: Vec3) -> Vec3 {
    if !agrees(wi, g.frame.n, g.ng) {
        return Vec3::ZERO;
    }
    g.at.eval(g.frame.to_local(wi))
}

#[inline(never)]
fn gltf_eval_past_terminator(g: &GltfVertex<'_>, wi: Vec3) -> Vec3 {
    g.at.eval(g.frame.to_local(wi))
}

#[inline(never)]
fn gltf_eval_pdf(g: &GltfVertex<'_>, wi: Vec3) -> (Vec3, Float) {
    if !agrees(wi, g.frame.n, g.ng) {
        return (Vec3::ZERO, 0.0);
    }
    g.at.eval_and_pdf(g.frame.to_local(wi))
}

#[inline(never)]
fn gltf_pdf(g: &GltfVertex<'_>, wi: Vec3) -> Float {
    if !agrees(wi, g.frame.n, g.ng) {
        return 0.0;
    }
    g.at.pdf(g.frame.to_local(wi))
}

#[inline(never)]
fn gltf_sample(g: &GltfVertex<'_>, u_lobe: Float, u: Vec2) -> Option<ScatterSample> {
    let s = g.at.sample(u_lobe, u)?;
    let wi = g.frame.to_world(s.wi);
    // Both normals must agree on the side `wi` leaves to, or light would leak
    // through the surface where the shading normal bends away.
    if !s.delta && !agrees(wi, g.frame.n, g.ng) {
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
