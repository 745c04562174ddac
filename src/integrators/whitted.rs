//! SPEC's Whitted-style integrator: Phong lighting with hard shadows, mirror
//! reflection and refraction, recursion limited by depth.

use super::Integrator;
use crate::material::Colours;
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
    let material = &scene.materials[hit.material.0 as usize];
    let [local_weight, reflect_weight, refract_weight] = material.albedo;
    // The colours at the hit: an untextured material's constants, read in place, or
    // a textured one's values there.
    let mut value = match material.maps {
        None => local_light(scene, ray, &hit, material, local_weight, rays),
        Some(_) => local_light(scene, ray, &hit, &material.at(hit.uv), local_weight, rays),
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

/// `Ka + Ke + al0 * (Phong lighting by the lights the hit point sees)`, with the
/// colours `surface` (one copy per kind of surface, so that untextured materials are
/// read in place).
#[inline(always)]
fn local_light(
    scene: &Scene,
    ray: &Ray,
    hit: &Hit,
    surface: &impl Colours,
    local_weight: Float,
    rays: &mut RayCounts,
) -> Vec3 {
    let mut value = surface.ambient() + surface.emission();
    if local_weight != 0.0 {
        let to_eye = -ray.dir;
        let mut local = Vec3::ZERO;
        for light in &scene.lights {
            // A light exactly at the hit point lights it from no direction.
            let Some(to_light) = try_unit(light.position - hit.p) else {
                continue;
            };
            let cos_light = hit.ns.dot(to_light);
            let mirrored = 2.0 * cos_light * hit.ns - to_light;
            let diffuse = surface.diffuse() * cos_light.max(0.0);
            // Clamped to 1 as well: rounding can push the cosine just past 1, which a
            // large `Ns` would raise to infinity.
            let cos_mirror = to_eye.dot(mirrored).clamp(0.0, 1.0);
            let specular = surface.specular() * cos_mirror.powf(surface.shininess());
            let lit = light.intensity * (diffuse + specular);
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
        value += local_weight * local;
    }
    value
}
