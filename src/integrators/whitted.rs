//! SPEC's Whitted-style integrator: Phong lighting with hard shadows, mirror
//! reflection and refraction, recursion limited by depth.

use std::time::{Duration, Instant};

use wide::f32x16;

use super::Integrator;
use super::phong_lanes::HitLanes;
use crate::bvh::PACKET_SIZE;
use crate::material::{Colours, PointLight};
use crate::math::{Float, Ray, Vec3, reflect, refract, saturate_finite, try_unit};
use crate::sampler::PixelSample;
use crate::scene::{Hit, Scene};
use crate::stats::RayCounts;

/// SPEC's lighting: deterministic, so it draws no sample dimensions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WhittedIntegrator {
    /// The remaining depth a camera ray's hit is shaded with
    /// ([`crate::RenderOptions::depth`]): 1 traces primary and shadow rays only.
    pub max_depth: u32,
}

impl Integrator for WhittedIntegrator {
    fn dimensions(&self) -> u32 {
        0
    }

    #[inline]
    fn radiance(
        &self,
        scene: &Scene,
        ray: &Ray,
        _: &mut PixelSample,
        rays: &mut RayCounts,
    ) -> Vec3 {
        trace(scene, ray, self.max_depth, false, rays)
    }
}

/// `inside` tells whether the ray travels inside an object: set by refracting into
/// one, cleared by refracting out. Inside, reflection is skipped, indices swap and
/// refraction is weighted 1 instead of `al2`.
///
/// Only surfaces with `al2 != 0` refract, inside or not: a ray that crossed a thin
/// refractive sheet (one surface, no back) and meets an opaque object is shaded there
/// and stops, as SPEC says, rather than refracting on through the object.
///
/// The result is always finite ([`saturate_finite`]), so that no sum or product of
/// huge scene values can reach the film as infinity or NaN.
fn trace(scene: &Scene, ray: &Ray, depth: u32, inside: bool, rays: &mut RayCounts) -> Vec3 {
    let Some(hit) = scene.intersect(ray) else {
        return Vec3::ZERO;
    };
    let shadows = ShadowRays {
        scene,
        ray,
        hit: &hit,
    };
    shade(scene, ray, &hit, depth, inside, rays, shadows)
}

/// Where the point lights' part of a hit's value comes from: shadow rays traced one by
/// one ([`ShadowRays`]) or a packet's answers ([`PacketAnswers`]).
trait DirectLight {
    /// The light of the point lights at the hit, for its colours `surface`.
    fn light(self, surface: &impl Colours, rays: &mut RayCounts) -> Vec3;
}

/// [`direct_light`] at `hit`.
struct ShadowRays<'a> {
    scene: &'a Scene,
    ray: &'a Ray,
    hit: &'a Hit,
}

impl DirectLight for ShadowRays<'_> {
    #[inline(always)]
    fn light(self, surface: &impl Colours, rays: &mut RayCounts) -> Vec3 {
        direct_light(self.scene, self.ray, self.hit, surface, rays)
    }
}

/// The value of `ray`'s hit `hit`: emission and ambient, the light of the point lights
/// (`direct`) weighted by `al0`, then mirror reflection and refraction traced ray by
/// ray.
#[inline(always)]
fn shade(
    scene: &Scene,
    ray: &Ray,
    hit: &Hit,
    depth: u32,
    inside: bool,
    rays: &mut RayCounts,
    direct: impl DirectLight,
) -> Vec3 {
    let material = &scene.materials[hit.material.0 as usize];
    let [local_weight, reflect_weight, refract_weight] = material.albedo;
    // The colours at the hit: an untextured material's constants, read in place, or
    // a textured one's values there.
    let mut value = match material.maps {
        None => local_light(material, local_weight, rays, direct),
        Some(_) => local_light(&material.at(hit.uv), local_weight, rays, direct),
    };

    if depth > 1 {
        if !inside && reflect_weight != 0.0 {
            let reflected = hit.spawn_ray(reflect(ray.dir, hit.ns));
            rays.reflected += 1;
            value += reflect_weight * trace(scene, &reflected, depth - 1, false, rays);
        }
        if refract_weight != 0.0 {
            let (eta, weight) = if inside {
                (material.ior, 1.0)
            } else {
                (1.0 / material.ior, refract_weight)
            };
            if let Some(dir) = refract(ray.dir, hit.ns, eta) {
                let refracted = hit.spawn_ray(dir);
                rays.refracted += 1;
                value += weight * trace(scene, &refracted, depth - 1, !inside, rays);
            }
        }
    }
    saturate_finite(value)
}

/// `Ka + Ke + al0 * direct light`, with the colours `surface` (one copy per kind of
/// surface, so that untextured materials are read in place).
#[inline(always)]
fn local_light(
    surface: &impl Colours,
    local_weight: Float,
    rays: &mut RayCounts,
    direct: impl DirectLight,
) -> Vec3 {
    let mut value = surface.ambient() + surface.emission();
    if local_weight != 0.0 {
        value += local_weight * direct.light(surface, rays);
    }
    value
}

/// Phong light of every point light at `hit`, a shadow ray per light that adds
/// something.
#[inline(always)]
fn direct_light(
    scene: &Scene,
    ray: &Ray,
    hit: &Hit,
    surface: &impl Colours,
    rays: &mut RayCounts,
) -> Vec3 {
    let mut local = Vec3::ZERO;
    for light in &scene.lights {
        let lit = light_term(ray, hit, surface, light);
        // Shading first, shadow ray second: a light that would add nothing (behind
        // a diffuse surface, say) needs no visibility test. The image is the same.
        if lit == Vec3::ZERO {
            continue;
        }
        let (shadow_ray, distance) = hit.spawn_ray_to(light.position);
        rays.shadow += 1;
        if !scene.occluded(&shadow_ray, distance) {
            local += lit;
        }
    }
    local
}

/// What `light` adds at `hit` if nothing blocks it (zero if nothing).
#[inline(always)]
fn light_term(ray: &Ray, hit: &Hit, surface: &impl Colours, light: &PointLight) -> Vec3 {
    // A light exactly at the hit point lights it from no direction.
    let Some(to_light) = try_unit(light.position - hit.p) else {
        return Vec3::ZERO;
    };
    let to_eye = -ray.dir;
    let cos_light = hit.ns.dot(to_light);
    let mirrored = 2.0 * cos_light * hit.ns - to_light;
    let diffuse = surface.diffuse() * cos_light.max(0.0);
    // Clamped to 1 as well: rounding can push the cosine just past 1, which a
    // large `Ns` would raise to infinity.
    let cos_mirror = to_eye.dot(mirrored).clamp(0.0, 1.0);
    let specular = surface.specular() * cos_mirror.powf(surface.shininess());
    light.intensity * (diffuse + specular)
}

/// Room for [`WhittedIntegrator::radiance_packet`]'s shadow rays, made once per run of
/// tiles so that no packet allocates.
#[derive(Debug, Default)]
pub struct PacketScratch {
    shadow_rays: Vec<Ray>,
    distances: Vec<Float>,
    /// Time spent in packet queries so far, when timed.
    tracing: Option<Duration>,
}

impl PacketScratch {
    /// Starts (or stops) adding up the time spent tracing packets, for `--stats`.
    pub fn time_tracing(&mut self, timed: bool) {
        self.tracing = timed.then_some(Duration::ZERO);
    }

    /// The time spent tracing packets since [`PacketScratch::time_tracing`]; zero
    /// when not timed.
    pub fn tracing_time(&self) -> Duration {
        self.tracing.unwrap_or_default()
    }

    /// Runs `f`, adding its time to the tracing time if timed.
    #[inline(always)]
    fn trace<T>(&mut self, f: impl FnOnce(&mut Self) -> T) -> T {
        match self.tracing {
            None => f(self),
            Some(before) => {
                let start = Instant::now();
                let result = f(self);
                self.tracing = Some(before + start.elapsed());
                result
            }
        }
    }
}

impl WhittedIntegrator {
    /// The values of up to [`PACKET_SIZE`] coherent camera rays (a tile of pixels)
    /// into `out`: exactly [`Integrator::radiance`] of each, with the camera rays and
    /// the shadow rays towards each point light traced as packets
    /// ([`Scene::intersect_packet`], [`Scene::occluded_packet`]); reflected and
    /// refracted rays are traced one by one.
    ///
    /// # Panics
    /// If `rays` is empty, longer than [`PACKET_SIZE`], or not as long as `out`.
    pub fn radiance_packet(
        &self,
        scene: &Scene,
        camera_rays: &[Ray],
        out: &mut [Vec3],
        rays: &mut RayCounts,
        scratch: &mut PacketScratch,
    ) {
        assert_eq!(camera_rays.len(), out.len(), "one value per ray");
        let count = camera_rays.len();
        let mut hits = [None; PACKET_SIZE];
        let hits = &mut hits[..count];
        scratch.trace(|_| scene.intersect_packet(camera_rays, hits));

        // The hits the point lights shade (those of materials with `al0 != 0`), with
        // their colours there, as lanes.
        let mut lanes = HitLanes::new();
        for (r, (ray, hit)) in camera_rays.iter().zip(hits.iter()).enumerate() {
            let Some(hit) = hit else {
                continue;
            };
            let material = &scene.materials[hit.material.0 as usize];
            if material.albedo[0] == 0.0 {
                continue;
            }
            match material.maps {
                None => lanes.set(r, ray, hit, material),
                Some(_) => lanes.set(r, ray, hit, &material.at(hit.uv)),
            }
        }

        // Light by light, as `direct_light`: what it adds to each hit, the shadow
        // rays of those it adds to, traced as a packet, and the sum of the unblocked
        // (adding a zero leaves a sum as it was: sums start at +0).
        let mut direct = [f32x16::ZERO; 3];
        scratch.shadow_rays.clear();
        scratch.shadow_rays.resize(count, camera_rays[0]);
        scratch.distances.clear();
        scratch.distances.resize(count, 0.0);
        if lanes.lanes() != 0 {
            for light in &scene.lights {
                let (lit, tested) =
                    lanes.light(light, &mut scratch.shadow_rays, &mut scratch.distances);
                if tested == 0 {
                    continue;
                }
                rays.shadow += u64::from(tested.count_ones());
                let blocked =
                    scratch.trace(|s| scene.occluded_packet(&s.shadow_rays, &s.distances, tested));
                let adds = f32x16::from(lane_mask(tested & !blocked));
                for (sum, lit) in direct.iter_mut().zip(lit) {
                    *sum += adds.select(lit, f32x16::ZERO);
                }
            }
        }

        let direct = direct.map(|sum| sum.to_array());
        for (r, ((ray, hit), value)) in camera_rays.iter().zip(hits.iter()).zip(out).enumerate() {
            let Some(hit) = hit else {
                *value = Vec3::ZERO;
                continue;
            };
            let light = PacketLight(Vec3::new(direct[0][r], direct[1][r], direct[2][r]));
            *value = shade(scene, ray, hit, self.max_depth, false, rays, light);
        }
    }
}

/// All ones in the lanes of `mask` (as `f32` bits), zeros elsewhere.
#[inline(always)]
fn lane_mask(mask: u32) -> [Float; PACKET_SIZE] {
    std::array::from_fn(|lane| Float::from_bits(if mask >> lane & 1 == 1 { !0 } else { 0 }))
}

/// The light of the point lights at a hit of a packet, summed by
/// [`WhittedIntegrator::radiance_packet`] (its shadow rays counted there).
struct PacketLight(Vec3);

impl DirectLight for PacketLight {
    #[inline(always)]
    fn light(self, _: &impl Colours, _: &mut RayCounts) -> Vec3 {
        self.0
    }
}
