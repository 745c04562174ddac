//! Path mode: a unidirectional path tracer with next-event estimation and multiple
//! importance sampling (power heuristic) for area lights, physical point lights, and
//! Russian roulette from the fifth bounce on. It follows Mitsuba 3's `path`
//! integrator step for step, so that both converge to the same image:
//!
//! - `max_depth` counts path segments: 1 shows only emitters seen directly, 2 adds
//!   direct light, and so on.
//! - An emitter hit by a scattered ray adds its radiance weighted against the chance
//!   that light sampling would have found the same point; after a mirror or glass
//!   bounce (which light sampling cannot follow) it adds it whole.
//! - Russian roulette from depth 5 keeps a path with probability
//!   `min(max(throughput) * eta^2, 0.95)`.
//!
//! With no light at all (no `Ke`, no `P`) the scene sits in a uniform white
//! environment, so that a model without lights still shows: path mode's default
//! lighting, as full mode's is a light rig at the camera; `--no-default-light`
//! ([`crate::RenderOptions::default_light`]) turns both off.
//!
//! Materials: [`crate::bsdf`]; lights: [`crate::lights`].

use super::Integrator;
use crate::bsdf::ScatteringParams;
use crate::material::Material;
use crate::math::{Float, Ray, Vec3, saturate_finite};
use crate::sampler::PixelSample;
use crate::scene::Scene;
use crate::stats::RayCounts;

/// Depth (in scattering events) from which Russian roulette may end a path, as
/// Mitsuba's `rr_depth` default.
const RUSSIAN_ROULETTE_DEPTH: u32 = 5;

/// Sample dimensions one bounce draws: light pick, light point (2), lobe, direction
/// (2), Russian roulette.
pub const DIMENSIONS_PER_BOUNCE: u32 = 7;

/// The path tracer for one scene: per-material scattering, derived once per render.
#[derive(Clone, Debug)]
pub struct PathIntegrator {
    scattering: Vec<ScatteringParams>,
    /// Most path segments.
    max_depth: u32,
    /// Radiance of rays that leave the scene: white when the scene has no light.
    environment: Vec3,
}

impl PathIntegrator {
    /// A path tracer for `scene` following at most `max_depth` segments; an unlit
    /// scene sits in a white sky if `default_light` says so, else in the dark.
    pub fn new(scene: &Scene, max_depth: u32, default_light: bool) -> PathIntegrator {
        let scattering = scene
            .materials
            .iter()
            .map(|m| ScatteringParams::new(m).0)
            .collect();
        let unlit = scene.lights.is_empty() && scene.area_lights.is_empty() && default_light;
        PathIntegrator {
            scattering,
            max_depth,
            environment: if unlit { Vec3::ONE } else { Vec3::ZERO },
        }
    }
}

impl Integrator for PathIntegrator {
    /// Sample dimensions one path draws at most.
    fn dimensions(&self) -> u32 {
        self.max_depth.saturating_mul(DIMENSIONS_PER_BOUNCE)
    }

    /// Radiance arriving along the camera ray `ray`, one path's estimate.
    fn radiance(
        &self,
        scene: &Scene,
        ray: &Ray,
        sample: &mut PixelSample,
        rays: &mut RayCounts,
    ) -> Vec3 {
        let mut ray = *ray;
        let mut radiance = Vec3::ZERO;
        let mut throughput = Vec3::ONE;
        // What the previous bounce knew, for weighing an emitter the path hits.
        let mut previous_delta = true;
        let mut previous_pdf = 0.0;
        let mut previous_point = ray.origin;
        let mut eta = 1.0;
        let mut depth = 0;
        loop {
            let Some(hit) = scene.intersect(&ray) else {
                radiance += throughput * self.environment;
                break;
            };
            let material = &scene.materials[hit.material.0 as usize];
            // A textured material's scattering is made for this hit from the values
            // of its maps here; an untextured one's was made once, in `new`.
            let textured = material.maps.as_ref().map(|_| material.at(hit.uv));
            let emission = textured.map_or(material.emission, |s| s.emission);
            if hit.front && emission != Vec3::ZERO {
                let weight = if previous_delta {
                    1.0
                } else {
                    let cos_light = hit.n.dot(-ray.dir);
                    let light_pdf =
                        scene
                            .area_lights
                            .pdf(hit.material, previous_point, hit.p, cos_light);
                    power_heuristic(previous_pdf, light_pdf)
                };
                radiance += throughput * emission * weight;
            }
            if depth + 1 >= self.max_depth {
                break;
            }
            let per_hit;
            let scattering = match &textured {
                Some(surface) => {
                    per_hit = ScatteringParams::at(material, surface);
                    &per_hit
                }
                None => &self.scattering[hit.material.0 as usize],
            };
            let wo = -ray.dir;

            // Next-event estimation: one point on an area light, and every point light.
            let u_pick = sample.next_1d();
            let u_light = sample.next_2d();
            if scattering.has_smooth_lobes() {
                if let Some(light) = scene.area_lights.sample(hit.p, u_pick, u_light) {
                    let f = scattering.eval(wo, light.direction, hit.ns, hit.n);
                    if f != Vec3::ZERO {
                        let (shadow_ray, distance) = hit.spawn_ray_to(light.point);
                        rays.shadow += 1;
                        // The light's own surface must not block the ray to it.
                        if !scene.occluded(&shadow_ray, distance * (1.0 - 1e-3)) {
                            let bsdf_pdf = scattering.pdf(wo, light.direction, hit.ns, hit.n);
                            let weight = power_heuristic(light.pdf, bsdf_pdf);
                            radiance += throughput
                                * f
                                * light.radiance
                                * (light.direction.dot(hit.ns) * weight / light.pdf);
                        }
                    }
                }
                for light in &scene.lights {
                    let to_light = light.position - hit.p;
                    let distance_squared = to_light.length_squared();
                    let direction = to_light / distance_squared.sqrt();
                    let f = scattering.eval(wo, direction, hit.ns, hit.n);
                    if f == Vec3::ZERO || !distance_squared.is_normal() {
                        continue;
                    }
                    let (shadow_ray, distance) = hit.spawn_ray_to(light.position);
                    rays.shadow += 1;
                    if !scene.occluded(&shadow_ray, distance) {
                        radiance += throughput
                            * f
                            * light.intensity
                            * (direction.dot(hit.ns) / distance_squared);
                    }
                }
            }

            // Scattering: where the path goes next.
            let u_lobe = sample.next_1d();
            let u_direction = sample.next_2d();
            let Some(scattered) =
                scattering.sample(wo, hit.ns, hit.n, hit.front, u_lobe, u_direction)
            else {
                break;
            };
            throughput *= scattered.weight;
            eta *= scattered.eta;
            previous_delta = scattered.delta;
            previous_pdf = scattered.pdf;
            previous_point = hit.p;
            ray = hit.spawn_ray(scattered.wi);
            rays.scattered += 1;
            depth += 1;

            let u_survive = sample.next_1d();
            let largest = throughput.max_element();
            // Zero (nothing more to carry) or NaN.
            if largest.is_nan() || largest <= 0.0 {
                break;
            }
            if depth >= RUSSIAN_ROULETTE_DEPTH {
                let keep = (largest * eta * eta).min(0.95);
                if u_survive >= keep {
                    break;
                }
                throughput /= keep;
            }
        }
        saturate_finite(radiance)
    }
}

/// Warnings about what path mode changes in `materials`: `Kd + Ks` scaled down to
/// conserve energy.
pub fn material_warnings(materials: &[Material]) -> Vec<String> {
    materials
        .iter()
        .filter(|m| ScatteringParams::new(m).1)
        .map(|m| {
            format!(
                "material '{}': Kd + Ks exceeds 1, scaled down in path mode to conserve energy",
                m.name
            )
        })
        .collect()
}

/// The power heuristic (exponent 2) of Veach's multiple importance sampling: the
/// weight of a sample of density `pdf` against another strategy's `other`.
#[inline]
fn power_heuristic(pdf: Float, other: Float) -> Float {
    let (a, b) = (pdf * pdf, other * other);
    if a + b > 0.0 && (a + b).is_finite() {
        a / (a + b)
    } else if pdf.is_infinite() {
        1.0
    } else {
        0.0
    }
}
