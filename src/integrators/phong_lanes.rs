//! Whitted shading's work per point light for the hits of a packet, sixteen lanes at
//! once: [`HitLanes::light`] is, lane by lane, exactly `whitted::light_term` followed
//! by [`Hit::spawn_ray_to`], so every lane's bits are the scalar code's.
//!
//! What "exactly" takes: glam's `Vec3` is three scalars, so a dot product is
//! `(x * x' + y * y') + z * z'`, `length` is `sqrt(dot)`, `try_normalize` multiplies by
//! `1 / length`, `max_element` is `if a > b { a } else { b }` from the last component
//! down, and `clamp` is two comparisons; here each is the same sequence of SIMD
//! operations (`+ - * /` and `sqrt` round correctly in every lane as in scalar code,
//! and nothing is fused into a multiply-add). `powf` stays the C library's, lane by
//! lane, and is skipped only where its result is known exactly ([`phong_power`]).

use wide::f32x16;

use crate::bvh::{PACKET_SIZE, lanes_of};
use crate::material::{Colours, Light};
use crate::math::{Float, Ray, Vec3, dot_lanes as dot};
use crate::scene::{Hit, SPAWN_OFFSET, TERMINATOR_COSINE};

/// Lanes of sixteen `f32`, as stored between packets (loaded into `f32x16` per light).
type Lanes = [Float; PACKET_SIZE];

/// The hits of a packet that the point lights shade, in structure-of-arrays form: what
/// `light_term` and `spawn_ray_to` read of the hit, its ray and its colours.
#[derive(Debug)]
pub(super) struct HitLanes {
    /// The hit points.
    p: [Lanes; 3],
    /// Geometric normals, facing the ray (`Hit::n`): which side shadow rays leave from.
    n: [Lanes; 3],
    /// Shading normals (`Hit::ns`).
    ns: [Lanes; 3],
    /// `Hit::lift`: where shadow rays at grazing light start from.
    lift: [Lanes; 3],
    /// `-ray.dir`.
    to_eye: [Lanes; 3],
    /// `Kd`.
    diffuse: [Lanes; 3],
    /// `Ks`.
    specular: [Lanes; 3],
    /// `Ns`.
    shininess: Lanes,
    /// How far shadow rays start off the surface (`Hit::offset_origin`'s scale).
    offset: Lanes,
    /// The lanes whose `Ks` is zero and `Ns` at least zero: their specular term is a
    /// zero whatever the cosine (the power is finite), so `powf` is not called.
    dull: u32,
    /// The lanes holding a hit.
    lanes: u32,
}

/// `[Float; PACKET_SIZE]` per component, lanes not set holding zeros.
const NO_LANES: [Lanes; 3] = [[0.0; PACKET_SIZE]; 3];

impl HitLanes {
    /// No hits yet.
    pub(super) fn new() -> HitLanes {
        HitLanes {
            p: NO_LANES,
            n: NO_LANES,
            ns: NO_LANES,
            lift: NO_LANES,
            to_eye: NO_LANES,
            diffuse: NO_LANES,
            specular: NO_LANES,
            shininess: [0.0; PACKET_SIZE],
            offset: [0.0; PACKET_SIZE],
            dull: 0,
            lanes: 0,
        }
    }

    /// The lanes holding a hit.
    pub(super) fn lanes(&self) -> u32 {
        self.lanes
    }

    /// Puts the hit `hit` of `ray`, with colours `surface`, in lane `lane`.
    #[inline(always)]
    pub(super) fn set(&mut self, lane: usize, ray: &Ray, hit: &Hit, surface: &impl Colours) {
        let to_eye = -ray.dir;
        let (diffuse, specular) = (surface.diffuse(), surface.specular());
        for axis in 0..3 {
            self.p[axis][lane] = hit.p[axis];
            self.n[axis][lane] = hit.n[axis];
            self.ns[axis][lane] = hit.ns[axis];
            self.lift[axis][lane] = hit.lift[axis];
            self.to_eye[axis][lane] = to_eye[axis];
            self.diffuse[axis][lane] = diffuse[axis];
            self.specular[axis][lane] = specular[axis];
        }
        let shininess = surface.shininess();
        self.shininess[lane] = shininess;
        // As `Hit::offset_origin`.
        self.offset[lane] = SPAWN_OFFSET * hit.p.abs().max_element().max(1.0);
        if specular == Vec3::ZERO && shininess >= 0.0 {
            self.dull |= 1 << lane;
        }
        self.lanes |= 1 << lane;
    }

    /// What `light` adds at each hit if nothing blocks it (`light_term`), and the
    /// lanes where that is not zero; for those lanes, the shadow ray towards the light
    /// and its length (`Hit::spawn_ray_to`) into `shadow_rays` and `distances`.
    #[inline(always)]
    pub(super) fn light(
        &self,
        light: &Light,
        shadow_rays: &mut [Ray],
        distances: &mut [Float],
    ) -> ([f32x16; 3], u32) {
        let zero = f32x16::ZERO;
        let one = f32x16::ONE;
        let load = |lanes: &[Lanes; 3]| lanes.map(f32x16::from);
        let position = light.position.to_array().map(f32x16::splat);
        let p = load(&self.p);
        let ns = load(&self.ns);

        // `try_unit(light.position - hit.p)`.
        let v = [0, 1, 2].map(|axis| position[axis] - p[axis]);
        let [ax, ay, az] = v.map(f32x16::abs);
        let largest = greater(ax, greater(ay, az));
        let scaled = v.map(|c| c / largest);
        let rcp = one / dot(scaled, scaled).sqrt();
        let valid =
            largest.simd_gt(zero) & largest.is_finite() & rcp.is_finite() & rcp.simd_gt(zero);
        let to_light = scaled.map(|c| c * rcp);

        let cos_light = dot(ns, to_light);
        let twice = f32x16::splat(2.0) * cos_light;
        let mirrored = [0, 1, 2].map(|axis| twice * ns[axis] - to_light[axis]);
        // `cos_light.max(0.0)`: NaN gives 0; the sign of a zero cosine cannot
        // reach the image (a zero `lit` is skipped, and sums start at +0).
        let facing = cos_light.simd_gt(zero).select(cos_light, zero);
        let diffuse = load(&self.diffuse).map(|kd| kd * facing);
        let cos_mirror = dot(load(&self.to_eye), mirrored);
        // `f32::clamp(0.0, 1.0)`: NaN stays NaN.
        let cos_mirror = cos_mirror.simd_lt(zero).select(zero, cos_mirror);
        let cos_mirror = cos_mirror.simd_gt(one).select(one, cos_mirror);

        let shaded = valid.to_bitmask() & self.lanes;
        let mut power = [0.0; PACKET_SIZE];
        let cosines = cos_mirror.as_array();
        for lane in lanes_of(shaded) {
            power[lane] = phong_power(
                cosines[lane],
                self.shininess[lane],
                self.dull >> lane & 1 == 1,
            );
        }
        let power = f32x16::from(power);
        let intensity = light.intensity.to_array().map(f32x16::splat);
        let specular = load(&self.specular);
        let lit = [0, 1, 2].map(|axis| {
            valid.select(
                intensity[axis] * (diffuse[axis] + specular[axis] * power),
                zero,
            )
        });
        let lit_lanes = (lit[0].simd_ne(zero) | lit[1].simd_ne(zero) | lit[2].simd_ne(zero))
            .to_bitmask()
            & shaded;
        if lit_lanes == 0 {
            return (lit, 0);
        }

        // `hit.spawn_ray_to(light.position)`: the origin off the surface on the side
        // of `v`, lifted towards the smooth surface by `terminator_share` of the
        // cosine to the light, then the unit direction and distance to the light
        // from there.
        let n = load(&self.n);
        let side = dot(v, n).simd_ge(zero).select(one, -one);
        let offset = side * f32x16::from(self.offset);
        let share = one - dot(n, to_light) / f32x16::splat(TERMINATOR_COSINE);
        let share = share.simd_lt(zero).select(zero, share);
        let share = share.simd_gt(one).select(one, share);
        let lift = load(&self.lift);
        let origin = [0, 1, 2].map(|axis| (p[axis] + n[axis] * offset) + lift[axis] * share);
        let to_target = [0, 1, 2].map(|axis| position[axis] - origin[axis]);
        let distance = dot(to_target, to_target).sqrt();
        let dir = to_target.map(|c| c / distance);
        let (origin, dir) = (origin.map(|c| c.to_array()), dir.map(|c| c.to_array()));
        let distance = distance.as_array();
        for lane in lanes_of(lit_lanes) {
            let at = |c: &[Lanes; 3]| Vec3::new(c[0][lane], c[1][lane], c[2][lane]);
            shadow_rays[lane] = Ray {
                origin: at(&origin),
                dir: at(&dir),
            };
            distances[lane] = distance[lane];
        }
        (lit, lit_lanes)
    }
}

/// glam's `max_element` step, `if a > b { a } else { b }`, lane by lane.
#[inline(always)]
fn greater(a: f32x16, b: f32x16) -> f32x16 {
    a.simd_gt(b).select(a, b)
}

/// `cosine.powf(shininess)` for a clamped cosine (in `[0, 1]`, or NaN), or a value
/// that gives the same specular term: without calling `powf` where C's `pow` is exact
/// by definition (a zero cosine raised to a positive power is a zero, one raised to
/// anything is one), and where `Ks` is zero (`dull`) and the power finite, which
/// leaves the term a zero whatever the power. A zero's sign is not kept: it cannot
/// reach the image (see [`HitLanes::light`]).
#[inline(always)]
fn phong_power(cosine: Float, shininess: Float, dull: bool) -> Float {
    if (dull && !cosine.is_nan()) || (cosine == 0.0 && shininess > 0.0) {
        0.0
    } else if cosine == 1.0 {
        1.0
    } else {
        cosine.powf(shininess)
    }
}
