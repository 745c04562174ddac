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
//! An environment ([`crate::lights::environment`]) lights the scene from infinitely
//! far away: light sampling picks it or an area light in proportion to their power
//! (the environment's over a disc of the scene's radius, as pbrt does), and a
//! scattered ray that leaves the scene sees it, weighted against light sampling.
//! A scene with no point light, no environment and no emitters that light it much
//! ([`Scene::unlit`]: LEDs on a model do not) sits in a procedural
//! studio ([`studio`]) before a neutral grey backdrop, so that a model without lights
//! shows as a model viewer shows it: path mode's default lighting, as full mode's is
//! a light rig at the camera; `--no-default-light`
//! ([`crate::RenderOptions::default_light`]) turns both off.
//!
//! A path inside a volume (`KHR_materials_volume`) is attenuated by Beer-Lambert's
//! law over the distance it travels there.
//!
//! Materials: [`crate::bxdfs`]; lights: [`crate::lights`].

use super::Integrator;
use super::aov::PixelAovs;
use crate::bvh::lanes_of;
use crate::bxdfs::gltf::GltfBsdf;
use crate::bxdfs::gltf_lanes::{self, LANES, PlainGather, V3, V3Gather};
use crate::bxdfs::mtl::{MtlMixture, reads_as_rough_dielectric};
use crate::bxdfs::{Bsdf, scattering_normal};
use crate::camera::Camera;
use crate::lights::LightSample;
use crate::lights::environment::{
    DirectionSample, Environment, EnvironmentDesc, EnvironmentRadiance, Leaving, STUDIO_BACKDROP,
    studio,
};
use crate::material::{LightKind, Material};
use crate::math::{Float, Ray, Vec2, Vec3, saturate_finite};
use crate::sampler::{PixelSample, PixelSampler};
use crate::scene::{BATCH, Hit, SPAWN_OFFSET, Scene, TERMINATOR_COSINE, terminator_share};
use crate::stats::RayCounts;
use std::f32::consts::PI;
use wide::f32x16;

// The batch's lanes are the plain BSDF's.
const _: () = assert!(BATCH == LANES);

/// Depth (in scattering events) from which Russian roulette may end a path, as
/// Mitsuba's `rr_depth` default.
const RUSSIAN_ROULETTE_DEPTH: u32 = 5;

/// Sample dimensions one bounce draws: light pick, light point (2), lobe, direction
/// (2), Russian roulette.
pub const DIMENSIONS_PER_BOUNCE: u32 = 7;

/// The path tracer for one scene: per-material scattering, derived once per render.
#[derive(Clone, Debug)]
pub struct PathIntegrator {
    scattering: Vec<Bsdf>,
    /// Per material, whether its hits are shaded sixteen at a time
    /// ([`PathIntegrator::step_plain`]): a plain glTF material
    /// ([`GltfBsdf::is_plain`]) without maps or emission.
    plain: Vec<bool>,
    /// Whether some material is plain: if none is, [`PathIntegrator::step_plain`]
    /// is not called (a Lambertian MTL scene's batches skip its look at every lane).
    any_plain: bool,
    /// Most path segments.
    max_depth: u32,
    /// What rays that leave the scene see: the scene's environment, or white when the
    /// scene has no light.
    environment: Option<Environment>,
    /// The probabilities that light sampling picks the environment, and an area
    /// light; the point lights share the rest.
    environment_probability: Float,
    area_probability: Float,
    /// Where each point light's share of the rest ends, in [0, 1], by power.
    point_cdf: Vec<Float>,
    /// What camera rays that leave the scene see, if not the environment.
    background: Option<Vec3>,
}

impl PathIntegrator {
    /// A path tracer for `scene` following at most `max_depth` segments; an unlit
    /// scene sits in the studio if `default_light` says so, else in the dark.
    pub fn new(scene: &Scene, max_depth: u32, default_light: bool) -> PathIntegrator {
        let scattering: Vec<Bsdf> = scene
            .materials
            .iter()
            .map(|m| match m.pbr_at(crate::math::Vec2::ZERO) {
                Some(values) => Bsdf::Gltf(GltfBsdf::new(&values)),
                None => Bsdf::of_mtl(m, None),
            })
            .collect();
        let plain: Vec<bool> = (scene.materials.iter().zip(&scattering))
            .map(|(m, bsdf)| {
                m.maps.is_none()
                    && m.emission == Vec3::ZERO
                    && !m.is_unlit()
                    && matches!(bsdf, Bsdf::Gltf(g) if g.is_plain())
            })
            .collect();
        let any_plain = plain.contains(&true);
        let unlit = scene.unlit && default_light;
        let (environment, background) = if unlit {
            let backdrop = scene.background.unwrap_or(STUDIO_BACKDROP);
            (Some(Environment::new(&studio())), Some(backdrop))
        } else {
            (scene.environment.clone(), scene.background)
        };
        PathIntegrator {
            scattering,
            plain,
            any_plain,
            max_depth,
            environment_probability: 0.0,
            area_probability: 0.0,
            point_cdf: Vec::new(),
            environment,
            background,
        }
        .weighed(scene)
    }

    /// The same path tracer with rays that leave the scene seeing a uniform
    /// environment of `radiance` (a white furnace at `Vec3::ONE`) instead of the
    /// scene's.
    pub fn with_environment(self, scene: &Scene, radiance: Vec3) -> PathIntegrator {
        PathIntegrator {
            environment: Some(Environment::new(&EnvironmentDesc {
                radiance: EnvironmentRadiance::Constant(radiance),
                strength: 1.0,
                rotation_degrees: 0.0,
            })),
            ..self
        }
        .weighed(scene)
    }

    /// The same path tracer with camera rays that leave the scene seeing `colour`
    /// rather than the environment (which still lights the scene).
    pub fn with_background(self, colour: Option<Vec3>) -> PathIntegrator {
        PathIntegrator {
            background: colour,
            ..self
        }
    }

    /// Sets the chances of light sampling picking the environment (0 for a uniform
    /// one, which scattering finds as well), an area light or a point light, in
    /// proportion to their power, as pbrt's power light sampler: an area light's is
    /// `pi` times its area times its radiance, the environment's `pi r^2` times its
    /// mean radiance times `4 pi` (`r` the scene's radius), a point light's (and a
    /// spot's) `4 pi I`, a directional light's `pi r^2 E`.
    fn weighed(mut self, scene: &Scene) -> PathIntegrator {
        let environment_power = match &self.environment {
            Some(environment) if !environment.is_constant() => {
                let r = scene.radius;
                (PI * r * r * 4.0 * PI * environment.mean_radiance()).max(Float::MIN_POSITIVE)
            }
            _ => 0.0,
        };
        let area_power = PI * scene.area_lights.total_power();
        let point_powers: Vec<Float> = (scene.lights.iter())
            .map(|l| {
                let intensity = mean(l.intensity.max(Vec3::ZERO));
                match l.kind {
                    // Illuminance over a disc of the scene's size.
                    LightKind::Directional { .. } => PI * scene.radius * scene.radius * intensity,
                    // A spot's cone is not counted: its power is at most a point's.
                    _ => 4.0 * PI * intensity,
                }
            })
            .collect();
        let point_power: Float = point_powers.iter().sum();
        let total = environment_power + area_power + point_power;
        if total > 0.0 && total.is_finite() {
            self.environment_probability = environment_power / total;
            self.area_probability = area_power / total;
        } else {
            // Powers of absurd size: an equal chance for each kind present.
            let kinds = [
                environment_power > 0.0,
                !scene.area_lights.is_empty(),
                !scene.lights.is_empty(),
            ];
            let count = kinds.iter().filter(|&&k| k).count().max(1) as Float;
            self.environment_probability = Float::from(u8::from(kinds[0])) / count;
            self.area_probability = Float::from(u8::from(kinds[1])) / count;
        }
        let mut running = 0.0;
        self.point_cdf = point_powers
            .iter()
            .map(|&p| {
                running += if point_power > 0.0 && point_power.is_finite() {
                    p / point_power
                } else {
                    1.0 / point_powers.len() as Float
                };
                running
            })
            .collect();
        if let Some(last) = self.point_cdf.last_mut() {
            *last = 1.0;
        }
        self
    }
}

/// The light that light sampling takes ([`PathIntegrator::pick_light`]).
#[derive(Clone, Copy, Debug)]
enum LightPick {
    /// The environment.
    Environment,
    /// An area light, picked among them by the value.
    Area(Float),
    /// The scene's point light `index` (or spot or directional light), with the
    /// probability of picking it.
    Point { index: usize, probability: Float },
    /// None: the scene has no light to sample.
    Nothing,
}

/// One path in flight: where it goes next and what it has gathered.
#[derive(Clone, Debug)]
struct PathState {
    /// The ray the path follows next.
    ray: Ray,
    sample: PixelSample,
    radiance: Vec3,
    throughput: Vec3,
    /// What the previous bounce knew, for weighing an emitter the path hits.
    previous_delta: bool,
    /// Whether the path is still the eye's: its camera ray, or one continuing it
    /// through smooth (delta) reflections and refractions only. Unlit surfaces
    /// (`KHR_materials_unlit`) show their colour to such paths alone.
    eye: bool,
    previous_pdf: Float,
    previous_point: Vec3,
    eta: Float,
    /// The attenuation coefficient of the volume the path is in (zero outside).
    medium: Vec3,
    /// Path segments traced so far.
    depth: u32,
    /// The light a shadow ray is testing: added to `radiance` if it gets through.
    unoccluded: Vec3,
}

impl PathState {
    fn new(ray: Ray, sample: PixelSample) -> PathState {
        PathState {
            ray,
            sample,
            radiance: Vec3::ZERO,
            throughput: Vec3::ONE,
            previous_delta: true,
            eye: true,
            previous_pdf: 0.0,
            previous_point: ray.origin,
            eta: 1.0,
            medium: Vec3::ZERO,
            depth: 0,
            unoccluded: Vec3::ZERO,
        }
    }
}

/// What one step of a path asks of the caller.
struct Step {
    /// A shadow ray towards a sampled light point, and the distance it must clear:
    /// if nothing blocks it, the state's `unoccluded` light is added.
    shadow: Option<(Ray, Float)>,
    /// Whether the path goes on along its new `ray`.
    alive: bool,
}

impl PathIntegrator {
    /// One step of a path: what it gathers where its ray ends (`hit`), then where it
    /// goes next. Point lights are tested here; the area light's shadow ray is left
    /// to the caller, so that the shadow rays of many paths can be traced together.
    #[inline(always)]
    fn step(
        &self,
        scene: &Scene,
        path: &mut PathState,
        hit: Option<Hit>,
        rays: &mut RayCounts,
    ) -> Step {
        let done = Step {
            shadow: None,
            alive: false,
        };
        let ray = path.ray;
        let Some(hit) = hit else {
            self.leave(path, None);
            return done;
        };
        if path.medium != Vec3::ZERO {
            path.throughput *= (-path.medium * hit.t).exp();
        }
        let material = &scene.materials[hit.material.0 as usize];
        if material.is_unlit() {
            // `KHR_materials_unlit`: the eye sees the base colour, whatever the
            // lights; the surface scatters nothing, so it shadows what lies behind it
            // but lights no other surface (a rasteriser's unlit material: it casts a
            // shadow map's shadow and takes part in no one's lighting).
            if path.eye
                && let Some(colour) = material.unlit_colour(hit.uv, hit.colour)
            {
                path.radiance += path.throughput * colour;
            }
            return done;
        }
        // A textured material's scattering is made for this hit from the values of
        // its maps here; an untextured one's was made once, in `new`.
        let textured = (material.maps.as_ref()).map(|_| material.at_point(hit.uv, hit.colour));
        let emission = textured.map_or(material.emission, |s| s.emission);
        if hit.front && emission != Vec3::ZERO {
            let weight = if path.previous_delta {
                1.0
            } else {
                let cos_light = hit.n.dot(-ray.dir);
                let light_pdf = self.area_probability
                    * scene
                        .area_lights
                        .pdf(hit.material, path.previous_point, hit.p, cos_light);
                power_heuristic(path.previous_pdf, light_pdf)
            };
            path.radiance += path.throughput * emission * weight;
        }
        if path.depth + 1 >= self.max_depth {
            return done;
        }
        let per_hit;
        let scattering = match &textured {
            Some(surface) => {
                per_hit = match material.pbr_at_point(hit.uv, hit.colour) {
                    Some(values) => Bsdf::Gltf(GltfBsdf::new(&values)),
                    None => Bsdf::of_mtl(material, Some(surface)),
                };
                &per_hit
            }
            None => &self.scattering[hit.material.0 as usize],
        };
        let wo = -ray.dir;
        let ns = scattering_normal(wo, hit.ns, hit.n);
        let coat_ns = match hit.coat_ns {
            Vec3::ZERO => Vec3::ZERO,
            coat_ns => coat_scattering_normal(wo, coat_ns, hit.n),
        };
        let bsdf = scattering.at(wo, ns, hit.n, coat_ns, hit.tangent, hit.front);
        let sample = &mut path.sample;

        // Next-event estimation: one light, chosen by power.
        let u_pick = sample.next_1d();
        let u_light = sample.next_2d();
        let mut shadow = None;
        if bsdf.has_smooth_lobes()
            && let Some((mut light, deferred)) = self.sample_light(scene, hit.p, u_pick, u_light)
        {
            if let (Some(sample), Some(environment)) = (&deferred, &self.environment) {
                // Read after the BSDF's value, if that is not zero.
                environment.prefetch_radiance(sample);
            }
            let (f, bsdf_pdf) = if light.delta {
                (bsdf.eval(light.direction), 0.0)
            } else {
                bsdf.eval_and_pdf(light.direction)
            };
            let (f, bsdf_pdf) = if f == Vec3::ZERO && past_terminator(&hit, ns, light.direction) {
                (bsdf.eval_past_terminator(light.direction), 0.0)
            } else {
                (f, bsdf_pdf)
            };
            if f != Vec3::ZERO {
                if let (Some(sample), Some(environment)) = (deferred, &self.environment) {
                    light.radiance = environment.sampled_radiance(&sample);
                }
                rays.shadow += 1;
                let weight = if light.delta {
                    1.0
                } else {
                    power_heuristic(light.pdf, bsdf_pdf)
                };
                path.unoccluded = path.throughput
                    * f
                    * light.radiance
                    * (light.direction.dot(ns).abs() * weight / light.pdf);
                shadow = Some(shadow_ray_towards(&hit, ns, &light));
            }
        }

        // Scattering: where the path goes next. A material of one lobe reads no
        // `u_lobe`: its dimension is passed over, undrawn.
        let u_lobe = if bsdf.picks_lobe() {
            sample.next_1d()
        } else {
            sample.skip_1d();
            0.0
        };
        let u_direction = sample.next_2d();
        let Some(scattered) = bsdf.sample(u_lobe, u_direction) else {
            return Step {
                shadow,
                alive: false,
            };
        };
        path.throughput *= scattered.weight;
        if scattered.wi.dot(hit.n) < 0.0 {
            // Through the surface: into the volume it bounds, or out of it.
            path.medium = match scattering.attenuation() {
                Some(attenuation) if hit.front => attenuation,
                _ => Vec3::ZERO,
            };
        }
        path.eta *= scattered.eta;
        path.previous_delta = scattered.delta;
        path.eye &= scattered.delta;
        path.previous_pdf = scattered.pdf;
        path.previous_point = hit.p;
        path.ray = hit.spawn_unit_ray(scattered.wi);
        rays.scattered += 1;
        path.depth += 1;

        let largest = path.throughput.max_element();
        // Zero (nothing more to carry) or NaN.
        let mut alive = !(largest.is_nan() || largest <= 0.0);
        // Russian roulette's dimension, drawn only where it is played.
        if alive && path.depth >= RUSSIAN_ROULETTE_DEPTH {
            let u_survive = sample.next_1d();
            let keep = (largest * path.eta * path.eta).min(0.95);
            if u_survive >= keep {
                alive = false;
            } else {
                path.throughput /= keep;
            }
        } else {
            sample.skip_1d();
        }
        Step { shadow, alive }
    }

    /// What a path that leaves the scene sees: the background or the environment,
    /// the latter weighed against light sampling; `leaving` is its direction
    /// converted for the environment already, if it was ([`Environment::leaving`]).
    #[inline(always)]
    fn leave(&self, path: &mut PathState, leaving: Option<Leaving>) {
        let Some(environment) = &self.environment else {
            return;
        };
        let (seen, weight) = match self.background {
            Some(colour) if path.depth == 0 => (colour, 1.0),
            _ => {
                let leaving = leaving.unwrap_or_else(|| environment.leaving(path.ray.dir));
                if path.previous_delta {
                    (environment.radiance_leaving(&leaving), 1.0)
                } else {
                    // Radiance and density from one conversion of the direction.
                    let (seen, pdf) = environment.radiance_and_pdf_leaving(&leaving);
                    let light_pdf = self.environment_probability * pdf;
                    (seen, power_heuristic(path.previous_pdf, light_pdf))
                }
            }
        };
        path.radiance += path.throughput * seen * weight;
    }

    /// Whether a path that leaves the scene looks its direction up in the
    /// environment (not for a camera ray that sees the background).
    #[inline(always)]
    fn sees_environment(&self, path: &PathState) -> bool {
        self.environment.is_some() && !(self.background.is_some() && path.depth == 0)
    }

    /// A point on a light seen from `from`, the light chosen by power: the
    /// environment (`u_pick` below its probability), an area light, or a point
    /// light; its density includes the choice. An environment's sample comes with
    /// its radiance left to look up ([`Environment::sampled_radiance`]: zero in the
    /// light sample until then), for where the BSDF scatters towards it.
    #[inline(always)]
    fn sample_light(
        &self,
        scene: &Scene,
        from: Vec3,
        u_pick: Float,
        u: Vec2,
    ) -> Option<(LightSample, Option<DirectionSample>)> {
        self.sample_picked(scene, from, self.pick_light(u_pick), u)
    }

    /// Which light light sampling takes by `u_pick`, by power.
    #[inline(always)]
    fn pick_light(&self, u_pick: Float) -> LightPick {
        let (p_environment, p_area) = (self.environment_probability, self.area_probability);
        if u_pick < p_environment {
            return LightPick::Environment;
        }
        let u_pick = u_pick - p_environment;
        if u_pick < p_area {
            return LightPick::Area(u_pick / p_area);
        }
        if self.point_cdf.is_empty() {
            return LightPick::Nothing;
        }
        let p_points = 1.0 - p_environment - p_area;
        let u_point = ((u_pick - p_area) / p_points).clamp(0.0, 1.0);
        let index = self
            .point_cdf
            .partition_point(|&c| c <= u_point)
            .min(self.point_cdf.len() - 1);
        let below = if index == 0 {
            0.0
        } else {
            self.point_cdf[index - 1]
        };
        LightPick::Point {
            index,
            probability: p_points * (self.point_cdf[index] - below),
        }
    }

    /// [`PathIntegrator::sample_light`] of the light `pick` names.
    #[inline(always)]
    fn sample_picked(
        &self,
        scene: &Scene,
        from: Vec3,
        pick: LightPick,
        u: Vec2,
    ) -> Option<(LightSample, Option<DirectionSample>)> {
        match pick {
            LightPick::Environment => {
                let sample = self.environment.as_ref()?.sample_direction(u)?;
                let light = LightSample {
                    point: from + sample.direction,
                    direction: sample.direction,
                    distance: Float::INFINITY,
                    radiance: Vec3::ZERO,
                    pdf: sample.pdf * self.environment_probability,
                    delta: false,
                };
                Some((light, Some(sample)))
            }
            LightPick::Area(u_area) => {
                let mut light = scene.area_lights.sample(from, u_area, u)?;
                light.pdf *= self.area_probability;
                Some((light, None))
            }
            LightPick::Point { index, probability } => {
                let light = &scene.lights[index];
                let incident = light.incident(from)?;
                if probability <= 0.0 {
                    return None;
                }
                // A point or spot gives `I / d^2` times its falloff, a directional
                // light its illuminance `E` from infinitely far away.
                let spread = if incident.distance.is_finite() {
                    incident.distance * incident.distance
                } else {
                    1.0
                };
                let light = LightSample {
                    point: light.position,
                    direction: incident.direction,
                    distance: incident.distance,
                    radiance: light.intensity * (incident.falloff / spread),
                    pdf: probability,
                    delta: true,
                };
                Some((light, None))
            }
            LightPick::Nothing => None,
        }
    }

    /// [`PathIntegrator::step`] of the lanes of `alive` whose hit is plain (an
    /// untextured, unlit plain glTF material, the path outside any volume and not
    /// at its last segment), sixteen lanes per instruction: the BSDF's value and
    /// density towards the light and its sample in [`gltf_lanes`], the MIS weight,
    /// the light's contribution, Russian roulette, the rays' origins and the
    /// samples of plain point lights and of an environment map (after their picks
    /// and alias lookups lane by lane) here; other light samples and the sample
    /// stream lane by lane, drawing what `step` draws in its order. Returns the
    /// lanes it stepped, those of them with a shadow ray (set in `shadow`) and
    /// those whose path ended.
    #[inline(never)]
    fn step_plain(
        &self,
        scene: &Scene,
        paths: &mut [PathState; BATCH],
        hits: &[Option<Hit>; BATCH],
        alive: u32,
        (shadow_rays, shadow_t): (&mut [Ray; BATCH], &mut [Float; BATCH]),
        rays: &mut RayCounts,
    ) -> (u32, u32, u32) {
        let mut gather = PlainGather::default();
        let mut points = V3Gather::splat(Vec3::ZERO);
        let mut lifts = V3Gather::splat(Vec3::ZERO);
        let mut lifted = 0u32;
        let mut plain = 0;
        for lane in lanes_of(alive) {
            let path = &paths[lane];
            let Some(hit) = &hits[lane] else { continue };
            let material = hit.material.0 as usize;
            if path.medium != Vec3::ZERO
                || path.depth + 1 >= self.max_depth
                || !self.plain[material]
            {
                continue;
            }
            if let Bsdf::Gltf(g) = &self.scattering[material]
                && let wo = -path.ray.dir
                && gather.set(lane, g, wo, scattering_normal(wo, hit.ns, hit.n), hit.n)
            {
                points.set(lane, hit.p);
                if hit.lift != Vec3::ZERO {
                    lifts.set(lane, hit.lift);
                    lifted |= 1 << lane;
                }
                plain |= 1 << lane;
            }
        }
        if plain == 0 {
            return (0, 0, 0);
        }
        let mut throughput = V3Gather::splat(Vec3::ZERO);
        let mut eta = [1.0; LANES];
        let mut roulette = [0.0; LANES];
        let mut u_lobe = [0.0; LANES];
        let mut u_direction = [[0.0; LANES]; 2];
        let mut u_survive = [0.0; LANES];
        // Light samples, by kind: a plain point light's (position, intensity and
        // probability gathered) and an environment map's (its map point) are
        // finished below sixteen at a time, any other (`others`) here.
        let (mut point_lanes, mut map_lanes) = (0u32, 0u32);
        let mut point_position = V3Gather::splat(Vec3::ZERO);
        let mut point_intensity = V3Gather::splat(Vec3::ZERO);
        let mut point_probability = [0.0; LANES];
        let mut map_samples = [None; LANES];
        let mut map_uv = [[0.5; LANES]; 2];
        let mut map_density = [0.0; LANES];
        let mut others = [None; LANES];
        let mut other_direction = V3Gather::splat(Vec3::Z);
        let mut other_pdf = [1.0; LANES];
        let mut other_distance = [0.0; LANES];
        let (mut other_lanes, mut other_delta) = (0u32, 0u32);
        let map = (self.environment.as_ref()).filter(|environment| !environment.is_constant());
        for lane in lanes_of(plain) {
            let path = &mut paths[lane];
            let Some(hit) = &hits[lane] else { continue };
            let sample = &mut path.sample;
            let u_pick = sample.next_1d();
            let u_light = sample.next_2d();
            u_lobe[lane] = sample.next_1d();
            let u = sample.next_2d();
            (u_direction[0][lane], u_direction[1][lane]) = (u.x, u.y);
            // Drawn before the path may end, where `step` would not draw it: the
            // ended path's stream is not read again.
            u_survive[lane] = sample.next_1d();
            throughput.set(lane, path.throughput);
            eta[lane] = path.eta;
            if path.depth + 1 >= RUSSIAN_ROULETTE_DEPTH {
                roulette[lane] = Float::from_bits(u32::MAX);
            }
            // (Sampled whatever the BSDF: it has smooth lobes but where it
            // scatters nothing, which the lanes' mask below leaves out.)
            match (self.pick_light(u_pick), map) {
                (LightPick::Point { index, probability }, _)
                    if scene.lights[index].is_plain_point() =>
                {
                    let light = &scene.lights[index];
                    point_position.set(lane, light.position);
                    point_intensity.set(lane, light.intensity);
                    point_probability[lane] = probability;
                    point_lanes |= 1 << lane;
                }
                (LightPick::Environment, Some(environment)) => {
                    if let Some(sample) = environment.sample_map(u_light) {
                        // Read after the BSDF's value, if that is not zero.
                        environment.prefetch_map_sample(&sample);
                        (map_uv[0][lane], map_uv[1][lane]) = (sample.uv.x, sample.uv.y);
                        map_density[lane] = sample.density;
                        map_samples[lane] = Some(sample);
                        map_lanes |= 1 << lane;
                    }
                }
                (pick, _) => {
                    if let Some((light, deferred)) = self.sample_picked(scene, hit.p, pick, u_light)
                    {
                        if let (Some(sample), Some(environment)) = (&deferred, &self.environment) {
                            environment.prefetch_radiance(sample);
                        }
                        other_direction.set(lane, light.direction);
                        other_pdf[lane] = light.pdf;
                        other_distance[lane] = light.distance;
                        other_lanes |= 1 << lane;
                        other_delta |= u32::from(light.delta) << lane;
                        others[lane] = Some((light, deferred));
                    }
                }
            }
        }

        // The light samples' directions, densities and distances: `Light::incident`
        // and `sample_picked` of plain point lights, `Environment::sample_direction`
        // of map points.
        let p = points.load();
        let to_light = point_position.load().minus(p);
        let point_distance = to_light.dot(to_light).sqrt();
        let point_probability = f32x16::from(point_probability);
        let is_normal = point_distance.simd_ge(f32x16::splat(Float::MIN_POSITIVE))
            & point_distance.simd_lt(f32x16::splat(Float::INFINITY));
        let point =
            gltf_lanes::mask(point_lanes) & is_normal & point_probability.simd_gt(f32x16::ZERO);
        let mut direction =
            V3::select(point, to_light.over(point_distance), other_direction.load());
        let mut light_pdf = point.select(point_probability, f32x16::from(other_pdf));
        let mut distance = point.select(point_distance, f32x16::from(other_distance));
        let mut on_map = f32x16::ZERO;
        if let (Some(environment), true) = (map, map_lanes != 0) {
            let (d, pdf) = environment.directions_of(map_uv.map(f32x16::from), map_density.into());
            on_map = gltf_lanes::mask(map_lanes) & pdf.simd_gt(f32x16::ZERO) & pdf.is_finite();
            let d = V3 {
                x: d[0],
                y: d[1],
                z: d[2],
            };
            direction = V3::select(on_map, d, direction);
            let pdf = pdf * f32x16::splat(self.environment_probability);
            light_pdf = on_map.select(pdf, light_pdf);
            distance = on_map.select(f32x16::splat(Float::INFINITY), distance);
        }
        let delta = gltf_lanes::mask(other_delta) | point;
        let lit = other_lanes | point.to_bitmask() | on_map.to_bitmask();

        // Next-event estimation: `step`'s, sixteen lanes at a time.
        let vertices = gather.at();
        let n = vertices.geometric_normals();
        let cos_shading = direction.dot(vertices.shading_normals());
        // `past_terminator`.
        let past_terminator = gltf_lanes::mask(lifted)
            & direction.dot(n).simd_le(f32x16::ZERO)
            & cos_shading.simd_gt(f32x16::ZERO);
        let (f, bsdf_pdf) = vertices.eval_and_pdf(direction, past_terminator);
        let throughput = throughput.load();
        let weight = delta.select(f32x16::ONE, power_heuristic_lanes(light_pdf, bsdf_pdf));
        let scale = cos_shading.abs() * weight / light_pdf;
        let lit = lit & (vertices.has_smooth_lobes() & f.nonzero()).to_bitmask();
        // The light arriving: a point light's `I / d^2`, the others' looked up.
        let mut radiance = V3Gather::splat(Vec3::ZERO);
        for lane in lanes_of(lit & !point.to_bitmask()) {
            let looked_up = match (&others[lane], &map_samples[lane], &self.environment) {
                (Some((light, None)), _, _) => light.radiance,
                (Some((_, Some(sample))), _, Some(environment)) => {
                    environment.sampled_radiance(sample)
                }
                (None, Some(sample), Some(environment)) => environment.map_sample_radiance(sample),
                _ => Vec3::ZERO,
            };
            radiance.set(lane, looked_up);
        }
        let point_radiance = point_intensity
            .load()
            .scale(f32x16::ONE / (point_distance * point_distance));
        let radiance = V3::select(point, point_radiance, radiance.load());
        let unoccluded = throughput.times(f).times(radiance).scale(scale);
        // `shadow_ray_towards`.
        let offset = spawn_offsets(p);
        let mut origin = spawn_origins(p, n, offset, direction);
        if lifted & lit != 0 {
            // `shadow_ray_towards`'s lift: `terminator_share` of it, on the side
            // the shading normal faces.
            let share = (f32x16::ONE - direction.dot(n) / f32x16::splat(TERMINATOR_COSINE))
                .max(f32x16::ZERO)
                .min(f32x16::ONE);
            let facing = cos_shading.simd_gt(f32x16::ZERO);
            origin = origin.plus(lifts.load().scale(facing.select(share, f32x16::ZERO)));
        }
        let clear = (distance - origin.minus(p).dot(direction)) * f32x16::splat(1.0 - 1e-3);
        for lane in lanes_of(lit) {
            rays.shadow += 1;
            paths[lane].unoccluded = unoccluded.lane(lane);
            shadow_rays[lane] = Ray {
                origin: origin.lane(lane),
                dir: direction.lane(lane),
            };
            shadow_t[lane] = clear.as_array()[lane];
        }

        // Scattering and Russian roulette.
        let sampled = vertices.sample(f32x16::from(u_lobe), u_direction.map(f32x16::from));
        let throughput = throughput.times(sampled.weight);
        let largest = throughput.max_element();
        // Zero (nothing more to carry) or NaN.
        let carries = largest.simd_gt(f32x16::ZERO);
        let eta = f32x16::from(eta);
        let keep = (largest * eta * eta).min(f32x16::splat(0.95));
        let roulette = f32x16::from(roulette) & carries;
        let survives = f32x16::from(u_survive).simd_lt(keep);
        let throughput = V3::select(roulette & survives, throughput.over(keep), throughput);
        let goes_on = sampled.valid & carries & (!roulette | survives);
        let (valid, goes_on) = (sampled.valid.to_bitmask(), goes_on.to_bitmask());
        // `Hit::spawn_unit_ray`.
        let origin = spawn_origins(p, n, offset, sampled.wi);
        for lane in lanes_of(plain & valid) {
            let path = &mut paths[lane];
            path.throughput = throughput.lane(lane);
            path.previous_delta = false;
            path.eye = false;
            path.previous_pdf = sampled.pdf.as_array()[lane];
            path.previous_point = p.lane(lane);
            path.ray = Ray {
                origin: origin.lane(lane),
                dir: sampled.wi.lane(lane),
            };
            rays.scattered += 1;
            path.depth += 1;
        }
        (plain, lit, plain & !goes_on)
    }

    /// Traces the paths `paths[..count]` to their ends together: each step's rays,
    /// then its shadow rays, as one batch; the first step's hits are `first_hits`
    /// when the caller traced them (for the extra outputs).
    fn trace_batch(
        &self,
        scene: &Scene,
        paths: &mut [PathState; BATCH],
        count: usize,
        mut first_hits: Option<[Option<Hit>; BATCH]>,
        rays: &mut RayCounts,
    ) {
        let mut alive = if count >= BATCH {
            u32::MAX >> (32 - BATCH)
        } else {
            (1u32 << count) - 1
        };
        let mut batch_rays = [paths[0].ray; BATCH];
        let mut hits = [None; BATCH];
        let mut shadow_rays = [paths[0].ray; BATCH];
        let mut shadow_t = [0.0; BATCH];
        while alive != 0 {
            for lane in lanes_of(alive) {
                batch_rays[lane] = paths[lane].ray;
            }
            match first_hits.take() {
                Some(first) => hits = first,
                None => scene.intersect_batch(&batch_rays, alive, &mut hits),
            }
            // Paths that leave the scene: their directions converted and their
            // texels asked of memory together, then read.
            let mut leaving = [None; BATCH];
            if let Some(environment) = &self.environment {
                for lane in lanes_of(alive) {
                    if hits[lane].is_none() && self.sees_environment(&paths[lane]) {
                        leaving[lane] = Some(environment.leaving(paths[lane].ray.dir));
                    }
                }
            }
            for lane in lanes_of(alive) {
                if hits[lane].is_none() {
                    self.leave(&mut paths[lane], leaving[lane]);
                    alive &= !(1 << lane);
                }
            }
            if let Some(environment) = &self.environment
                && self.environment_probability > 0.0
            {
                // Light sampling will pick the environment for most of these paths
                // and read a slot of its alias table at random, most often a cache
                // miss: fetching all of them first overlaps the misses (the samples
                // are peeked at here, drawn again in `step`).
                for lane in lanes_of(alive) {
                    let path = &paths[lane];
                    if path.depth + 1 < self.max_depth {
                        let mut sample = path.sample.clone();
                        if sample.next_1d() < self.environment_probability {
                            environment.prefetch(sample.next_2d());
                        }
                    }
                }
            }
            let (plain, shadowed_plain, ended) = if self.any_plain {
                self.step_plain(
                    scene,
                    paths,
                    &hits,
                    alive,
                    (&mut shadow_rays, &mut shadow_t),
                    rays,
                )
            } else {
                (0, 0, 0)
            };
            let mut shadowed = shadowed_plain;
            let scalar = alive & !plain;
            alive &= !ended;
            for lane in lanes_of(scalar) {
                let step = self.step(scene, &mut paths[lane], hits[lane], rays);
                if let Some((ray, t)) = step.shadow {
                    shadow_rays[lane] = ray;
                    shadow_t[lane] = t;
                    shadowed |= 1 << lane;
                }
                if !step.alive {
                    alive &= !(1 << lane);
                }
            }
            if shadowed != 0 {
                let blocked = scene.occluded_batch(&shadow_rays, &shadow_t, shadowed);
                for lane in lanes_of(shadowed & !blocked) {
                    let path = &mut paths[lane];
                    path.radiance += path.unoccluded;
                }
            }
        }
    }
}

impl Integrator for PathIntegrator {
    /// Sample dimensions one path draws at most.
    fn dimensions(&self) -> u32 {
        self.max_depth.saturating_mul(DIMENSIONS_PER_BOUNCE)
    }

    /// Radiance arriving along the camera ray `ray` (whose closest hit is `hit`),
    /// one path's estimate.
    fn radiance_of(
        &self,
        scene: &Scene,
        ray: &Ray,
        hit: Option<Hit>,
        sample: &mut PixelSample,
        rays: &mut RayCounts,
    ) -> Vec3 {
        let mut path = PathState::new(*ray, sample.clone());
        let mut first_hit = Some(hit);
        loop {
            let hit = match first_hit.take() {
                Some(hit) => hit,
                None => scene.intersect(&path.ray),
            };
            let step = self.step(scene, &mut path, hit, rays);
            if let Some((shadow_ray, t)) = step.shadow
                && !scene.occluded(&shadow_ray, t)
            {
                path.radiance += path.unoccluded;
            }
            if !step.alive {
                break;
            }
        }
        *sample = path.sample;
        saturate_finite(path.radiance)
    }

    /// The pixel's paths, [`BATCH`] at a time, each traced as [`Self::radiance`]
    /// traces it; with extra outputs, their camera rays' hits are traced for the
    /// outputs and the paths alike ([`PixelAovs::intersect`], ray by ray: the
    /// batch's hits are bit for bit the same).
    fn pixel(
        &self,
        scene: &Scene,
        camera: &Camera,
        sampler: &PixelSampler,
        (column, row, width): (u32, u32, u32),
        rays: &mut RayCounts,
        aovs: &mut PixelAovs,
    ) -> Vec3 {
        let count = sampler.count();
        let pixel_index = row as u64 * width as u64 + column as u64;
        let (x0, y0) = (column as Float, row as Float);
        let mut sum = Vec3::ZERO;
        let mut first = 0;
        // The batch's paths, filled in place batch by batch: an array made whole
        // and moved in is a 2.3 KB copy a batch, whose speed hangs on where the
        // stack puts the two (a copy to 8 bytes past its source, modulo 4 KiB,
        // stalls every load: 4K aliasing, measured at 8% of a Cornell box's time).
        let blank = PathState::new(
            Ray::new(Vec3::ZERO, Vec3::Z),
            sampler.sample(pixel_index, 0),
        );
        let mut paths: [PathState; BATCH] = std::array::from_fn(|_| blank.clone());
        while first < count {
            let size = (count - first).min(BATCH as u32) as usize;
            for (i, path) in paths.iter_mut().enumerate() {
                let sample = first + (i as u32).min(size as u32 - 1);
                let offset = sampler.offset(pixel_index, sample);
                let values = sampler.sample(pixel_index, sample);
                let ray = camera.sample_ray(x0 + offset.x, y0 + offset.y, &values);
                *path = PathState::new(ray, values);
            }
            rays.primary += size as u64;
            let first_hits = aovs.wanted().then(|| {
                let mut hits = [None; BATCH];
                for (hit, path) in hits.iter_mut().zip(&paths[..size]) {
                    *hit = aovs.intersect(scene, &path.ray);
                }
                hits
            });
            self.trace_batch(scene, &mut paths, size, first_hits, rays);
            for path in &paths[..size] {
                sum += saturate_finite(path.radiance);
            }
            first += size as u32;
        }
        sum / count as Float
    }
}

/// Warnings about what path mode changes in `materials`: `Kd + Ks` scaled down to
/// conserve energy, one line for all the materials it concerns.
pub fn material_warnings(materials: &[Material]) -> Vec<String> {
    let scaled: Vec<&str> = materials
        .iter()
        .filter(|m| m.pbr.is_none() && !reads_as_rough_dielectric(m) && MtlMixture::new(m).1)
        .map(|m| m.name.as_str())
        .collect();
    let names = |count: usize| {
        let mut list = scaled[..count.min(3)]
            .iter()
            .map(|name| format!("'{name}'"))
            .collect::<Vec<_>>()
            .join(", ");
        if count > 3 {
            list.push_str(", ...");
        }
        list
    };
    match scaled.len() {
        0 => Vec::new(),
        1 => vec![format!(
            "material {}: Kd + Ks exceeds 1, scaled down in path mode to conserve energy",
            names(1)
        )],
        count => vec![format!(
            "{count} materials ({}): Kd + Ks exceeds 1, scaled down in path mode to conserve energy",
            names(count)
        )],
    }
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

/// The shadow ray from `hit` towards the light point of `light`, and the distance it
/// must clear: the point lies `light.distance` along `light.direction` from the hit
/// point, a little less from the offset origin, and the light's own surface must not
/// block the ray to it.
#[inline(always)]
fn shadow_ray_towards(hit: &Hit, ns: Vec3, light: &LightSample) -> (Ray, Float) {
    let mut ray = hit.spawn_unit_ray(light.direction);
    if hit.lift != Vec3::ZERO && light.direction.dot(ns) > 0.0 {
        // From the smooth surface as far as the light grazes the triangle
        // (as `Hit::spawn_ray_to`), on the side the shading normal faces: a light
        // through the surface (a thin transmitting one) is tested from behind it,
        // not through it. Inline, all of it: an out-of-line call taking the hit or
        // the light sample by reference kept them in memory for the whole step
        // (1.035x the CPU of the Cornell box, which never takes this branch).
        ray.origin += hit.lift * terminator_share(hit.n.dot(light.direction));
    }
    let distance = light.distance - (ray.origin - hit.p).dot(light.direction);
    (ray, distance * (1.0 - 1e-3))
}

/// [`scattering_normal`] of a clear coat's own normal, out of line: rare, and
/// inlined a second time it weighed on every vertex's code.
#[inline(never)]
fn coat_scattering_normal(wo: Vec3, coat_ns: Vec3, ng: Vec3) -> Vec3 {
    scattering_normal(wo, coat_ns, ng)
}

/// Whether light sampling's unit `direction` from `hit` lies past the terminator of
/// a smooth mesh's flat triangle: above the shading surface (of unit normal `ns`)
/// but not the geometric one, where the hit has a smooth surface above it to start
/// a shadow ray from ([`Hit::lift`]). The surface is lit there as its shading
/// normal says ([`crate::bxdfs::BsdfAt::eval_past_terminator`]) wherever that
/// shadow ray gets out (Hanika, "Hacking the Shadow Terminator"): on a coarse
/// sphere the light's edge runs smooth rather than in steps of whole triangles,
/// and under an environment the triangles do not show as patches.
#[inline(always)]
fn past_terminator(hit: &Hit, ns: Vec3, direction: Vec3) -> bool {
    hit.lift != Vec3::ZERO && direction.dot(hit.n) <= 0.0 && direction.dot(ns) > 0.0
}

/// How far [`Hit::spawn_ray`] moves the origins of rays leaving the sixteen hit
/// points `p` off their surfaces: `SPAWN_OFFSET` times the largest coordinate's
/// magnitude, at least 1.
#[inline(always)]
fn spawn_offsets(p: V3) -> f32x16 {
    let largest = V3 {
        x: p.x.abs(),
        y: p.y.abs(),
        z: p.z.abs(),
    }
    .max_element();
    f32x16::splat(SPAWN_OFFSET) * largest.max(f32x16::ONE)
}

/// `Hit::offset_origin` of sixteen lanes: the origins of rays leaving the points `p`
/// of geometric normals `n` along `dir`, `offset` ([`spawn_offsets`]) off the
/// surface on the side `dir` leaves towards.
#[inline(always)]
fn spawn_origins(p: V3, n: V3, offset: f32x16, dir: V3) -> V3 {
    let side = dir
        .dot(n)
        .simd_ge(f32x16::ZERO)
        .select(f32x16::ONE, -f32x16::ONE);
    p.plus(n.scale(side * offset))
}

/// [`power_heuristic`] of sixteen lanes.
#[inline(always)]
fn power_heuristic_lanes(pdf: f32x16, other: f32x16) -> f32x16 {
    let (a, b) = (pdf * pdf, other * other);
    let sum = a + b;
    let fallback = pdf.is_inf().select(f32x16::ONE, f32x16::ZERO);
    (sum.simd_gt(f32x16::ZERO) & sum.is_finite()).select(a / sum, fallback)
}

#[inline]
fn mean(v: Vec3) -> Float {
    (v.x + v.y + v.z) / 3.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::BvhParams;
    use crate::integrators::aov::PixelAovs;
    use crate::options::{Mode, RenderOptions};
    use crate::sampler::PixelSampler;
    use std::path::Path;

    /// The path-mode Cornell box and the camera and options of its reference, at
    /// `width` x `height` pixels, `spp` samples each.
    fn cornell(width: u32, height: u32, spp: u32) -> (Scene, RenderOptions) {
        let path = Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/tests/data/path/cornell.obj"
        ));
        let scene = Scene::build(
            crate::formats::load_mesh(path).unwrap(),
            &BvhParams::default(),
        );
        let options = RenderOptions {
            mode: Mode::Path,
            width,
            height,
            samples_per_pixel: spp,
            look_from: Vec3::new(0.0, 1.0, 3.4),
            look_to: Vec3::new(0.0, 1.0, 0.0),
            fov_degrees: 40.0,
            depth: 64,
            ..RenderOptions::default()
        };
        (scene, options)
    }

    /// Asserts that every pixel `integrator` traces in batches equals the mean of
    /// its paths traced one by one (`radiance`), bit for bit, and that both count
    /// the same rays.
    fn assert_batches_equal_single_paths(
        scene: &Scene,
        options: &RenderOptions,
        integrator: &PathIntegrator,
    ) {
        let camera = Camera::for_options(options);
        let spp = options.samples_per_pixel;
        let sampler = PixelSampler::new(spp, integrator.dimensions());
        let (mut batched_rays, mut single_rays) = (RayCounts::default(), RayCounts::default());
        for row in 0..options.height {
            for column in 0..options.width {
                let at = (column, row, options.width);
                let no_outputs = &mut PixelAovs::none();
                let batched =
                    integrator.pixel(scene, &camera, &sampler, at, &mut batched_rays, no_outputs);
                let single = sampler.average(column, row, options.width, |x, y, sample| {
                    single_rays.primary += 1;
                    integrator.radiance(scene, &camera.ray(x, y), sample, &mut single_rays)
                });
                assert_eq!(
                    batched.to_array().map(f32::to_bits),
                    single.to_array().map(f32::to_bits),
                    "pixel ({column}, {row})"
                );
            }
        }
        assert_eq!(batched_rays, single_rays);
        assert!(batched_rays.scattered > batched_rays.primary);
    }

    /// Tracing a pixel's paths sixteen at a time gives each path exactly the value
    /// it gets traced alone: the batched `pixel` equals the mean of `radiance` over
    /// the same samples, bit for bit, with batches of 16 and a last one of 4 whose
    /// paths end at different depths.
    #[test]
    fn batched_pixels_equal_paths_traced_one_by_one() {
        let (scene, options) = cornell(12, 9, 20);
        let integrator = PathIntegrator::new(&scene, options.depth, true);
        assert_batches_equal_single_paths(&scene, &options, &integrator);
    }

    /// `integrator` lit by an environment map as well (seen through the box's open
    /// front), which light sampling picks a fair share of the time.
    fn under_a_sky(integrator: PathIntegrator, scene: &Scene) -> PathIntegrator {
        let (width, height) = (32, 16);
        let texels: Vec<Float> = (0..width * height)
            .flat_map(|i| {
                let (x, y) = ((i % width) as Float, (i / width) as Float);
                [
                    1.0 + x / 4.0,
                    0.5 + y,
                    if x == 5.0 && y == 3.0 { 500.0 } else { 0.3 },
                ]
            })
            .collect();
        let texture =
            crate::textures::Texture::from_f32("sky.hdr".into(), width, height, 3, texels).unwrap();
        let mut integrator = integrator;
        integrator.environment = Some(Environment::new(&EnvironmentDesc {
            radiance: EnvironmentRadiance::Map(std::sync::Arc::new(texture)),
            // Dim enough that light sampling picks the box's light a fair share.
            strength: 0.05,
            rotation_degrees: 30.0,
        }));
        integrator.background = None;
        let integrator = integrator.weighed(scene);
        assert!(
            integrator.environment_probability > 0.05 && integrator.area_probability > 0.05,
            "{} {}",
            integrator.environment_probability,
            integrator.area_probability
        );
        integrator
    }

    /// The same under an environment map seen through the box's open front and
    /// sampled beside its light: the batch looks up its leaving paths' radiance and
    /// prefetches its light samples' alias slots and texels ahead of shading them,
    /// and must still give each path what it gets alone.
    #[test]
    fn batched_pixels_equal_paths_traced_one_by_one_under_an_environment_map() {
        let (scene, options) = cornell(10, 8, 20);
        let integrator = PathIntegrator::new(&scene, options.depth, true);
        let integrator = under_a_sky(integrator, &scene);
        assert_batches_equal_single_paths(&scene, &options, &integrator);
    }

    /// Sixteen rays' origins at once (`spawn_offsets`, `spawn_origins`) are
    /// `Hit::spawn_unit_ray`'s, lane by lane and bit for bit, for points near and
    /// far from the origin and directions on both sides of the surface.
    #[test]
    fn sixteen_spawned_origins_are_each_hits() {
        let mut uniform = crate::math::xorshift(0x2545_F491_4F6C_DD1D);
        let mut next = move || uniform() - 0.5;
        for batch in 0..100 {
            let hits: [Hit; BATCH] = std::array::from_fn(|lane| {
                let scale = [0.01, 0.9, 3.0, 250.0][(batch + lane) % 4];
                let n = Vec3::new(next(), next(), next()).normalize();
                Hit {
                    t: 1.0,
                    p: Vec3::new(next(), next(), next()) * scale,
                    n,
                    ns: n,
                    uv: Vec2::ZERO,
                    coat_ns: Vec3::ZERO,
                    tangent: Vec3::ZERO,
                    lift: Vec3::ZERO,
                    colour: Vec3::ONE,
                    material: crate::material::MaterialId(0),
                    front: true,
                }
            });
            let dirs: [Vec3; BATCH] =
                std::array::from_fn(|_| Vec3::new(next(), next(), next()).normalize());
            let p = V3::from_vecs(&hits.map(|h| h.p));
            let n = V3::from_vecs(&hits.map(|h| h.n));
            let origins = spawn_origins(p, n, spawn_offsets(p), V3::from_vecs(&dirs));
            for (lane, hit) in hits.iter().enumerate() {
                let expected = hit.spawn_unit_ray(dirs[lane]).origin;
                assert_eq!(
                    origins.lane(lane).to_array().map(Float::to_bits),
                    expected.to_array().map(Float::to_bits),
                    "lane {lane}: {hit:?} towards {}",
                    dirs[lane]
                );
            }
        }
    }

    /// The Cornell box with its walls and blocks plain glTF materials (metals,
    /// dielectrics and a blend, of several roughnesses), its area light as it is
    /// and a point light beside it (light sampling picks either).
    fn plain_cornell(width: u32, height: u32, spp: u32) -> (Scene, RenderOptions) {
        let (mut scene, options) = cornell(width, height, spp);
        let point = Vec3::new(0.3, 1.5, 0.4);
        (scene.lights).push(crate::material::Light::point(point, Vec3::splat(0.4)));
        for (i, m) in scene.materials.iter_mut().enumerate() {
            if m.emission == Vec3::ZERO {
                m.pbr = Some(Box::new(crate::material::pbr::PbrMaterial {
                    base_color: m.diffuse,
                    metallic: [0.0, 1.0, 0.3][i % 3],
                    roughness: [0.5, 0.3, 0.8][i % 3],
                    ..Default::default()
                }));
            }
        }
        (scene, options)
    }

    /// Plain hits shaded sixteen at a time (`step_plain`, lanes of mixed
    /// materials beside lanes that `step` shades: the light, the last segment)
    /// give each path the radiance it gets traced alone by the scalar `step`, bit
    /// for bit, with Russian roulette, and under an environment map as well.
    #[test]
    fn plain_lanes_equal_paths_traced_one_by_one() {
        let (scene, options) = plain_cornell(10, 8, 20);
        let integrator = PathIntegrator::new(&scene, options.depth, true);
        assert!(integrator.plain.iter().filter(|&&p| p).count() >= 3);
        assert!(integrator.plain.contains(&false));
        let point_share = |i: &PathIntegrator| 1.0 - i.area_probability - i.environment_probability;
        assert!(point_share(&integrator) > 0.1 && integrator.area_probability > 0.1);
        assert_batches_equal_single_paths(&scene, &options, &integrator);
        let integrator = under_a_sky(integrator, &scene);
        assert!(point_share(&integrator) > 0.05);
        assert_batches_equal_single_paths(&scene, &options, &integrator);
    }
}
