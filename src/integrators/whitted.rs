//! SPEC's Whitted-style integrator: Phong lighting with hard shadows, mirror
//! reflection and refraction, recursion limited by depth.

use wide::f32x16;

use super::phong_lanes::HitLanes;
use super::{Band, Integrator, TileContext, TraceClock, trace_band_by_pixel};
use crate::bvh::PACKET_SIZE;
use crate::bxdfs::microfacet::split_sum;
use crate::bxdfs::scattering_normal;
use crate::lights::environment::studio_radiance;
use crate::material::pbr::PbrValues;
use crate::material::{Colours, Light};
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
    fn radiance_of(
        &self,
        scene: &Scene,
        ray: &Ray,
        hit: Option<Hit>,
        _: &mut PixelSample,
        rays: &mut RayCounts,
    ) -> Vec3 {
        trace_from(scene, ray, hit, self.max_depth, false, rays)
    }

    fn band_rows(&self, context: &TileContext) -> u32 {
        if Self::traces_packets(context) {
            PACKET_TILE
        } else {
            1
        }
    }

    /// Through a pinhole, the camera rays of each 4x4 tile of the band (the pixel
    /// centres at one sample per pixel; with more, each sample's rays in turn), and
    /// their shadow rays, traced as packets
    /// ([`WhittedIntegrator::radiance_packet`]): bit for bit the values (and the
    /// extra outputs) of [`Integrator::pixel`], which traces every other band.
    fn trace_band(
        &self,
        context: &TileContext,
        band: Band<'_>,
        rays: &mut RayCounts,
        clock: &mut TraceClock,
    ) {
        if !Self::traces_packets(context) {
            trace_band_by_pixel(self, context, band, rays);
            return;
        }
        let width = band.width as usize;
        let mut scratch = PacketScratch::default();
        let mut camera_rays = [Ray::new(Vec3::ZERO, Vec3::Z); PACKET_SIZE];
        let mut hits = [None; PACKET_SIZE];
        let mut values = [Vec3::ZERO; PACKET_SIZE];
        let mut shaded = [Vec3::ZERO; PACKET_SIZE];
        let mut aovs = band.aovs;
        for left in (band.left..band.left + band.width).step_by(PACKET_TILE as usize) {
            let columns = (band.left + band.width - left).min(PACKET_TILE);
            for top in (band.top..band.top + band.rows).step_by(PACKET_TILE as usize) {
                let rows = (band.top + band.rows - top).min(PACKET_TILE);
                let count = (columns * rows) as usize;
                // Ray `k` of the tile is the band's pixel `band_pixel(k)`.
                let first = ((top - band.top) * band.width + left - band.left) as usize;
                let band_pixel =
                    |k: usize| first + k / columns as usize * width + k % columns as usize;
                let samples = context.sampler.count();
                for sample in 0..samples {
                    if samples == 1 {
                        context
                            .camera
                            .tile_rays(left, top, columns, rows, &mut camera_rays);
                    } else {
                        // The tile's pixels' rays of this sample, made as
                        // `Integrator::pixel` makes them.
                        for (k, ray) in camera_rays[..count].iter_mut().enumerate() {
                            let column = left + k as u32 % columns;
                            let row = top + k as u32 / columns;
                            let pixel_index =
                                u64::from(row) * u64::from(context.image_width) + u64::from(column);
                            let offset = context.sampler.offset(pixel_index, sample);
                            let values = context.sampler.sample(pixel_index, sample);
                            *ray = context.camera.sample_ray(
                                column as Float + offset.x,
                                row as Float + offset.y,
                                &values,
                            );
                        }
                    }
                    rays.primary += count as u64;
                    let (camera_rays, hits) = (&camera_rays[..count], &mut hits[..count]);
                    clock.trace(|| {
                        aovs.intersect_packet(context.scene, camera_rays, hits, band_pixel)
                    });
                    let shaded = &mut shaded[..count];
                    self.shade_packet(
                        context.scene,
                        camera_rays,
                        hits,
                        shaded,
                        rays,
                        &mut scratch,
                        clock,
                    );
                    // Summed sample by sample from zero and divided as
                    // `PixelSampler::average` does: the same bits.
                    for (value, shaded) in values[..count].iter_mut().zip(shaded.iter()) {
                        *value = match (samples, sample) {
                            (1, _) => *shaded,
                            (_, 0) => Vec3::ZERO + *shaded,
                            _ => *value + *shaded,
                        };
                    }
                }
                if samples > 1 {
                    for value in &mut values[..count] {
                        *value /= samples as Float;
                    }
                }
                let mut values = values[..count].iter();
                for row in (top - band.top) as usize..(top - band.top + rows) as usize {
                    let start = row * width + (left - band.left) as usize;
                    for pixel in &mut band.pixels[start..start + columns as usize] {
                        *pixel = *values.next().expect("one value per pixel");
                    }
                }
            }
        }
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
#[inline(always)]
fn trace(scene: &Scene, ray: &Ray, depth: u32, inside: bool, rays: &mut RayCounts) -> Vec3 {
    trace_from(scene, ray, scene.intersect(ray), depth, inside, rays)
}

/// [`trace`] of `ray` whose closest hit `hit` is known.
fn trace_from(
    scene: &Scene,
    ray: &Ray,
    hit: Option<Hit>,
    depth: u32,
    inside: bool,
    rays: &mut RayCounts,
) -> Vec3 {
    let Some(mut hit) = hit else {
        return Vec3::ZERO;
    };
    as_full_mode_shades(scene, ray, &mut hit);
    let shadows = ShadowRays {
        scene,
        ray,
        hit: &hit,
    };
    shade(scene, ray, &hit, depth, inside, rays, shadows)
}

/// `hit` as full mode shades it. SPEC's Phong material in a scene with its own
/// lights keeps the shading normal as the hit has it (turned to face the ray), and
/// its shadow rays start an epsilon off the triangle (no [`Hit::lift`]), as the
/// reference images show it. Under the default rig, and for a physically based
/// material, both of them ours, a normal that faces away from the eye (along a
/// low-poly silhouette, in a normal map at a grazing view) is bent towards it as
/// path mode bends it ([`scattering_normal`]), which would otherwise shade a dark
/// fringe round smooth-shaded models; the rig's shadow rays keep the lift.
#[inline(always)]
fn as_full_mode_shades(scene: &Scene, ray: &Ray, hit: &mut Hit) {
    if !scene.lit_by_rig() {
        hit.lift = Vec3::ZERO;
    }
    if hit.ns != hit.n
        && (scene.lit_by_rig() || scene.materials[hit.material.0 as usize].pbr.is_some())
    {
        hit.ns = scattering_normal(-ray.dir, hit.ns, hit.n);
    }
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
    if material.is_unlit() {
        return unlit(scene, ray, hit, depth, inside, rays);
    }
    let [local_weight, reflect_weight, refract_weight] = material.albedo;
    // The colours at the hit: an untextured material's constants, read in place, or
    // a textured one's values there.
    let mut value = match material.maps {
        None => local_light(material, local_weight, rays, direct),
        Some(_) => local_light(
            &material.at_point(hit.uv, hit.colour),
            local_weight,
            rays,
            direct,
        ),
    };

    if scene.lit_by_rig()
        && !inside
        && let Some(values) = material.pbr_at_point(hit.uv, hit.colour)
    {
        value += studio_reflection(scene, ray, hit, &values, depth, rays);
    }

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
    saturate_finite(over_behind(scene, ray, hit, depth, inside, rays, value))
}

/// The value of an unlit surface's hit (`KHR_materials_unlit`): its base colour
/// there, whatever the lights (no ambient, no reflection); a blended one over what
/// lies behind it, as for any surface.
#[inline(never)]
fn unlit(
    scene: &Scene,
    ray: &Ray,
    hit: &Hit,
    depth: u32,
    inside: bool,
    rays: &mut RayCounts,
) -> Vec3 {
    let material = &scene.materials[hit.material.0 as usize];
    let value = (material.unlit_colour(hit.uv, hit.colour)).unwrap_or(Vec3::ZERO);
    saturate_finite(over_behind(scene, ray, hit, depth, inside, rays, value))
}

/// `value`, a surface's at `hit`, over what lies behind it where the surface is
/// blended (in a scene that blends in layers), as a rasterizer blends it; with no
/// depth left it stays opaque.
#[inline]
fn over_behind(
    scene: &Scene,
    ray: &Ray,
    hit: &Hit,
    depth: u32,
    inside: bool,
    rays: &mut RayCounts,
    value: Vec3,
) -> Vec3 {
    let material = &scene.materials[hit.material.0 as usize];
    if scene.blend_in_layers()
        && depth > 1
        && let Some(cutout) = material.cutout()
        && cutout.blend
    {
        let alpha = cutout.alpha(hit.uv).clamp(0.0, 1.0);
        if alpha < 1.0 {
            return alpha * value + (1.0 - alpha) * behind(scene, ray, hit, depth, inside, rays);
        }
    }
    value
}

/// What lies behind `hit` along `ray`: the ray traced on through the surface, with
/// `depth` left, as SPEC's refraction through a sheet of index 1.
#[inline(never)]
fn behind(
    scene: &Scene,
    ray: &Ray,
    hit: &Hit,
    depth: u32,
    inside: bool,
    rays: &mut RayCounts,
) -> Vec3 {
    let onward = hit.spawn_ray(ray.dir);
    rays.refracted += 1;
    trace(scene, &onward, depth - 1, inside, rays)
}

/// What a physically based surface at `hit`, with its `values` there, reflects of the
/// studio under full mode's default rig, which has no surroundings of its own: a
/// metal would otherwise show black but for the rig's two highlights. Its
/// [`studio_reflectance`] times the studio in the mirror direction
/// ([`studio_radiance`]), blurred by a lobe of `2 alpha` radians (about the width
/// of a GGX lobe of `alpha = roughness^2` after reflection). Smooth surfaces
/// (roughness below 0.5) also mirror the scene: the traced reflection, weighed
/// `1 - 2 roughness` against the studio, where the mirror ray hits something (with
/// `depth` left, as SPEC's reflection). The studio is clamped at 1, full mode's white
/// under the rig: a chrome's reflection of the key light would otherwise set the
/// image's white point and dim every other surface.
#[inline(never)]
fn studio_reflection(
    scene: &Scene,
    ray: &Ray,
    hit: &Hit,
    values: &PbrValues,
    depth: u32,
    rays: &mut RayCounts,
) -> Vec3 {
    let reflectance = studio_reflectance(values, hit.ns.dot(-ray.dir));
    if reflectance == Vec3::ZERO {
        return Vec3::ZERO;
    }
    let dir = reflect(ray.dir, hit.ns);
    let alpha = values.roughness * values.roughness;
    let mut seen = Vec3::splat(studio_radiance(dir, 2.0 * alpha).min(1.0));
    let sharpness = 1.0 - 2.0 * values.roughness;
    if sharpness > 0.0 && depth > 1 {
        let reflected = hit.spawn_ray(dir);
        rays.reflected += 1;
        let mirrored = scene.intersect(&reflected);
        if mirrored.is_some() {
            let traced = trace_from(scene, &reflected, mirrored, depth - 1, false, rays);
            seen = sharpness * traced + (1.0 - sharpness) * seen;
        }
    }
    reflectance * seen
}

/// How much of its surroundings a physically based surface with `values` reflects
/// about its mirror direction, seen at cosine `cos_view` to the normal: the
/// directional albedo of its GGX lobe, `f0 a + f90 b` ([`split_sum`], image-based
/// lighting's split sum, as a model viewer computes it), `f0` being
/// [`PbrValues::phong`]'s (the dielectric's turning into the base colour as the
/// material turns metal) and `f90` the dielectric's `specular` turning into 1.
fn studio_reflectance(values: &PbrValues, cos_view: Float) -> Vec3 {
    let (a, b) = split_sum(cos_view, values.roughness * values.roughness);
    let f0 = values
        .dielectric_f0()
        .lerp(values.base_color, values.metallic);
    let f90 = values.specular + (1.0 - values.specular) * values.metallic;
    f0 * a + Vec3::splat(f90 * b)
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
        if !light.is_plain_point() {
            local += other_light(scene, ray, hit, surface, light, rays);
            continue;
        }
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

/// What a light that is not a plain point light (a spot, a directional light, a
/// point light with a range) adds at `hit`, its shadow ray traced: SPEC's Phong
/// terms towards it, times its intensity, cone attenuation and range window (full
/// mode's point lights do not fall off with distance, so neither do these).
#[inline(never)]
fn other_light(
    scene: &Scene,
    ray: &Ray,
    hit: &Hit,
    surface: &impl Colours,
    light: &Light,
    rays: &mut RayCounts,
) -> Vec3 {
    let Some(incident) = light.incident(hit.p) else {
        return Vec3::ZERO;
    };
    let lit = light.intensity * incident.falloff * phong(ray, hit, surface, incident.direction);
    if lit == Vec3::ZERO {
        return Vec3::ZERO;
    }
    let (shadow_ray, distance) = if incident.distance.is_finite() {
        hit.spawn_ray_to(light.position)
    } else {
        (hit.spawn_ray(incident.direction), Float::INFINITY)
    };
    rays.shadow += 1;
    if scene.occluded(&shadow_ray, distance) {
        Vec3::ZERO
    } else {
        lit
    }
}

/// What `light` adds at `hit` if nothing blocks it (zero if nothing).
#[inline(always)]
fn light_term(ray: &Ray, hit: &Hit, surface: &impl Colours, light: &Light) -> Vec3 {
    // A light exactly at the hit point lights it from no direction.
    let Some(to_light) = try_unit(light.position - hit.p) else {
        return Vec3::ZERO;
    };
    light.intensity * phong(ray, hit, surface, to_light)
}

/// SPEC's Phong terms, `Kd cos + Ks cos_mirror^Ns`, for light arriving at `hit` from
/// the unit direction `to_light`.
#[inline(always)]
fn phong(ray: &Ray, hit: &Hit, surface: &impl Colours, to_light: Vec3) -> Vec3 {
    let to_eye = -ray.dir;
    let cos_light = hit.ns.dot(to_light);
    let mirrored = 2.0 * cos_light * hit.ns - to_light;
    let diffuse = surface.diffuse() * cos_light.max(0.0);
    // Clamped to 1 as well: rounding can push the cosine just past 1, which a
    // large `Ns` would raise to infinity.
    let cos_mirror = to_eye.dot(mirrored).clamp(0.0, 1.0);
    let specular = surface.specular() * cos_mirror.powf(surface.shininess());
    diffuse + specular
}

/// Room for [`WhittedIntegrator::radiance_packet`]'s shadow rays, made once per band
/// so that no packet allocates.
#[derive(Debug, Default)]
pub struct PacketScratch {
    shadow_rays: Vec<Ray>,
    distances: Vec<Float>,
}

/// Side of the square pixel tiles whose camera rays are traced as one packet.
const PACKET_TILE: u32 = 4;
const _: () = assert!((PACKET_TILE * PACKET_TILE) as usize == PACKET_SIZE);

impl WhittedIntegrator {
    /// Whether bands are traced as packets of 4x4 pixels' rays, sample by sample:
    /// through a pinhole, whose rays share the eye (a thin lens's do not).
    fn traces_packets(context: &TileContext) -> bool {
        context.camera.is_pinhole()
    }
}

impl WhittedIntegrator {
    /// The values of up to [`PACKET_SIZE`] coherent camera rays (a tile of pixels)
    /// into `out`: exactly [`Integrator::radiance`] of each, with the camera rays and
    /// the shadow rays towards each point light traced as packets
    /// ([`Scene::intersect_packet`], [`Scene::occluded_packet`]), and the point
    /// lights' terms computed for all the hits at once in SIMD lanes
    /// (`integrators::phong_lanes`); reflected and refracted rays are traced one by one.
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
        clock: &mut TraceClock,
    ) {
        let mut hits = [None; PACKET_SIZE];
        let hits = &mut hits[..camera_rays.len()];
        clock.trace(|| scene.intersect_packet(camera_rays, hits));
        self.shade_packet(scene, camera_rays, hits, out, rays, scratch, clock);
    }

    /// [`WhittedIntegrator::radiance_packet`] of the camera rays `camera_rays` whose
    /// closest hits `hits` are known (traced as a packet).
    ///
    /// # Panics
    /// If `camera_rays` is empty, longer than [`PACKET_SIZE`], or not as long as
    /// `hits` and `out`.
    #[allow(clippy::too_many_arguments)]
    fn shade_packet(
        &self,
        scene: &Scene,
        camera_rays: &[Ray],
        hits: &mut [Option<Hit>],
        out: &mut [Vec3],
        rays: &mut RayCounts,
        scratch: &mut PacketScratch,
        clock: &mut TraceClock,
    ) {
        assert_eq!(camera_rays.len(), out.len(), "one value per ray");
        assert_eq!(camera_rays.len(), hits.len(), "one hit per ray");
        let count = camera_rays.len();
        for (ray, hit) in camera_rays.iter().zip(hits.iter_mut()) {
            if let Some(hit) = hit {
                as_full_mode_shades(scene, ray, hit);
            }
        }

        // Spots, directional lights and ranges are shaded hit by hit
        // (`direct_light`); the lanes know plain point lights only.
        if !scene.lights.iter().all(Light::is_plain_point) {
            for ((ray, hit), value) in camera_rays.iter().zip(hits.iter()).zip(out) {
                *value = match hit {
                    None => Vec3::ZERO,
                    Some(hit) => {
                        let direct = ShadowRays { scene, ray, hit };
                        shade(scene, ray, hit, self.max_depth, false, rays, direct)
                    }
                };
            }
            return;
        }

        // The hits the point lights shade (those of materials with `al0 != 0`), with
        // their colours there, as lanes.
        let mut lanes = HitLanes::new();
        for (r, (ray, hit)) in camera_rays.iter().zip(hits.iter()).enumerate() {
            let Some(hit) = hit else {
                continue;
            };
            let material = &scene.materials[hit.material.0 as usize];
            if material.albedo[0] == 0.0 || material.is_unlit() {
                continue;
            }
            match material.maps {
                None => lanes.set(r, ray, hit, material),
                Some(_) => lanes.set(r, ray, hit, &material.at_point(hit.uv, hit.colour)),
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
                let blocked = clock.trace(|| {
                    scene.occluded_packet(&scratch.shadow_rays, &scratch.distances, tested)
                });
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

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use super::*;
    use crate::material::{MaterialId, MaterialMaps};
    use crate::math::Vec2;
    use crate::sampler::PixelSampler;
    use crate::scene::packet_tests::generated_description;
    use crate::textures::{Texture, TextureMap};
    use crate::{BvhParams, Camera};

    /// A 4 x 4 RGB checkerboard map.
    fn checker_map() -> Option<TextureMap> {
        let texels = (0..16)
            .flat_map(|i| {
                if (i + i / 4) % 2 == 0 {
                    [250, 240, 30]
                } else {
                    [20, 90, 200]
                }
            })
            .collect();
        let texture = Texture::from_u8("checker.png".into(), 4, 4, 3, texels).unwrap();
        Some(TextureMap::new(Arc::new(texture)))
    }

    /// [`generated_description`]'s scene with every kind of surface Whitted shading
    /// tells apart, materials changing from triangle to triangle (so packets mix
    /// them), and lights in front of, behind and far from the surfaces.
    fn shading_scene(n: u32, with_spheres: bool, seed: u64) -> Scene {
        let mut d = generated_description(n, with_spheres, seed);
        let base = d.materials[0].clone();
        let mut textured = base.clone();
        textured.maps = Some(Box::new(MaterialMaps {
            diffuse: checker_map(),
            specular: checker_map(),
            ..MaterialMaps::default()
        }));
        let mut emissive = base.clone();
        emissive.emission = Vec3::new(0.4, 0.1, 0.0);
        let mut reflective_only = base.clone();
        reflective_only.albedo = [0.0, 0.9, 0.0];
        let mut dull = base.clone();
        dull.specular = Vec3::ZERO;
        dull.shininess = 1.0;
        let mut sharp = base.clone();
        sharp.shininess = 1000.0;
        let mut flat = base.clone();
        flat.shininess = 0.0;
        d.materials
            .extend([textured, emissive, reflective_only, dull, sharp, flat]);
        let kinds = d.materials.len() as u32;
        // Texture coordinates from the positions, for the textured triangles.
        d.texcoords = d.positions.iter().map(|p| Vec2::new(p.x, p.z)).collect();
        d.triangle_texcoords = d.triangles.iter().map(|t| Some(t.positions)).collect();
        for (i, triangle) in d.triangles.iter_mut().enumerate() {
            triangle.material = MaterialId((i as u32 / 3 + i as u32 / 200) % kinds);
        }
        for (k, sphere) in d.spheres.iter_mut().enumerate() {
            sphere.material = MaterialId(k as u32 % kinds);
        }
        d.lights.extend([
            // Under the height field: behind most surfaces the camera sees.
            Light::point(Vec3::new(0.2, -0.8, 0.1), Vec3::new(0.9, 0.2, 0.4)),
            // On the height field's plane, among the random triangles.
            Light::point(Vec3::new(0.0, 0.3, 0.0), Vec3::splat(0.25)),
            // So bright that sums overflow to infinity.
            Light::point(Vec3::new(-0.3, 3.0, 1.0), Vec3::new(3e38, 0.0, 1.0)),
        ]);
        Scene::build(d, &BvhParams::default())
    }

    /// `radiance_packet` of the 4x4 tiles (narrower and shorter at the right and
    /// bottom edges) of a `width` x `height` image from `look_from` against
    /// `radiance` of each pixel's ray: bitwise the same values, and as many rays.
    fn check_packets(scene: &Scene, look_from: Vec3, depth: u32) {
        let (width, height) = (94, 62);
        let camera = Camera::new(look_from, Vec3::new(0.0, 0.1, 0.0), 50.0, width, height);
        let integrator = WhittedIntegrator { max_depth: depth };
        let mut scratch = PacketScratch::default();
        let (mut packet_rays, mut single_rays) = (RayCounts::default(), RayCounts::default());
        let sampler = PixelSampler::new(1, 0);
        let mut checked = 0;
        for top in (0..height).step_by(4) {
            for left in (0..width).step_by(4) {
                let rays: Vec<Ray> = (top..(top + 4).min(height))
                    .flat_map(|row| (left..(left + 4).min(width)).map(move |c| (c, row)))
                    .map(|(column, row)| camera.pixel_ray(column, row))
                    .collect();
                let mut values = vec![Vec3::ZERO; rays.len()];
                integrator.radiance_packet(
                    scene,
                    &rays,
                    &mut values,
                    &mut packet_rays,
                    &mut scratch,
                    &mut TraceClock::default(),
                );
                for (k, (ray, value)) in rays.iter().zip(&values).enumerate() {
                    let mut sample = sampler.sample(0, 0);
                    let single = integrator.radiance(scene, ray, &mut sample, &mut single_rays);
                    assert_eq!(
                        value.to_array().map(Float::to_bits),
                        single.to_array().map(Float::to_bits),
                        "ray {k} of the tile at ({left}, {top}) from {look_from}"
                    );
                    checked += usize::from(single != Vec3::ZERO);
                }
            }
        }
        assert!(checked > 1000, "{checked} pixels lit");
        assert!(
            single_rays.shadow > 2000,
            "{} shadow rays",
            single_rays.shadow
        );
        assert_eq!(packet_rays.shadow, single_rays.shadow);
        assert_eq!(packet_rays.reflected, single_rays.reflected);
        assert_eq!(packet_rays.refracted, single_rays.refracted);
    }

    #[test]
    fn packets_shade_exactly_as_single_rays() {
        for (n, spheres, seed) in [(40, false, 1), (57, true, 2)] {
            let scene = shading_scene(n, spheres, seed);
            for look_from in [
                Vec3::new(0.0, 1.5, 2.0),
                Vec3::new(1.7, 0.4, -1.1),
                Vec3::new(0.0, 3.0, 0.0001),
                // From below: the height field's back faces.
                Vec3::new(0.3, -1.5, 1.0),
            ] {
                for depth in [1, 4] {
                    check_packets(&scene, look_from, depth);
                }
            }
        }
    }

    /// A value's bits, all zeros counted as +0 and all NaNs as one NaN: what of a
    /// light's term can reach the image.
    fn visible_bits(x: Float) -> u32 {
        if x == 0.0 {
            0
        } else if x.is_nan() {
            Float::NAN.to_bits()
        } else {
            x.to_bits()
        }
    }

    /// `HitLanes::light` against `light_term` and `Hit::spawn_ray_to` hit by hit, on
    /// random hits and colours and on the awkward cases: a light exactly at the hit
    /// point, behind the surface, `Ks = 0`, `Ns` of 0, 1 and 1000, overflowing
    /// intensities, hits lifted towards a smooth surface (`Hit::lift`) or not.
    #[test]
    fn lanes_compute_the_light_terms_and_shadow_rays_of_single_hits() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let unit = |rng: &mut rand::rngs::StdRng| {
            let v = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            );
            try_unit(v).unwrap_or(Vec3::Y)
        };
        let (mut lit_lanes, mut powers) = (0, 0);
        for round in 0..4000 {
            let light = Light::point(
                Vec3::new(
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-3.0..3.0),
                ),
                match round % 5 {
                    0 => Vec3::new(3e38, 1.0, 0.0),
                    _ => Vec3::new(0.7, 0.5, rng.random_range(0.0..2.0)),
                },
            );
            let mut lanes = HitLanes::new();
            let mut cases = Vec::new();
            for lane in 0..PACKET_SIZE {
                if rng.random_range(0..8) == 0 {
                    continue;
                }
                let mut material = crate::material::Material::named("m");
                material.diffuse = Vec3::new(rng.random_range(0.0..1.0), 0.5, 0.25);
                material.specular = match lane % 4 {
                    0 => Vec3::ZERO,
                    1 => Vec3::new(1e38, 0.5, 0.0),
                    _ => Vec3::splat(rng.random_range(0.0..1.0)),
                };
                material.shininess =
                    [0.0, 1.0, 1000.0, rng.random_range(0.5..200.0)][lane % 4 / 2 + round % 2 * 2];
                let n = unit(&mut rng);
                let ns = if lane % 3 == 0 { n } else { unit(&mut rng) };
                let ray = Ray::new(Vec3::new(0.0, 0.0, 5.0), unit(&mut rng));
                let p = if lane == 5 {
                    // A light exactly at the hit point.
                    light.position
                } else {
                    Vec3::new(
                        rng.random_range(-2.0..2.0),
                        rng.random_range(-2.0..2.0),
                        rng.random_range(-2.0..2.0),
                    )
                };
                let hit = Hit {
                    t: 1.0,
                    p,
                    n,
                    ns,
                    uv: Vec2::ZERO,
                    coat_ns: Vec3::ZERO,
                    tangent: Vec3::ZERO,
                    // Half the hits lifted towards a smooth surface.
                    lift: if lane % 2 == 0 {
                        Vec3::ZERO
                    } else {
                        unit(&mut rng) * rng.random_range(0.0..0.1)
                    },
                    colour: Vec3::ONE,
                    material: MaterialId(0),
                    front: true,
                };
                lanes.set(lane, &ray, &hit, &material);
                cases.push((lane, ray, hit, material));
            }
            let mut shadow_rays = [Ray::new(Vec3::ZERO, Vec3::Z); PACKET_SIZE];
            let mut distances = [0.0; PACKET_SIZE];
            let (lit, mask) = lanes.light(&light, &mut shadow_rays, &mut distances);
            for (lane, ray, hit, material) in cases {
                let expected = light_term(&ray, &hit, &material, &light);
                let got = Vec3::new(
                    lit[0].as_array()[lane],
                    lit[1].as_array()[lane],
                    lit[2].as_array()[lane],
                );
                assert_eq!(
                    got.to_array().map(visible_bits),
                    expected.to_array().map(visible_bits),
                    "lane {lane} of round {round}: {got} against {expected}"
                );
                assert_eq!(mask >> lane & 1 == 1, expected != Vec3::ZERO, "lane {lane}");
                if expected != Vec3::ZERO {
                    let (shadow, distance) = hit.spawn_ray_to(light.position);
                    assert_eq!(format!("{:?}", shadow_rays[lane]), format!("{shadow:?}"));
                    assert_eq!(distances[lane].to_bits(), distance.to_bits());
                    lit_lanes += 1;
                    powers += usize::from(expected.x != 0.0 && material.specular.x != 0.0);
                }
            }
        }
        assert!(
            lit_lanes > 20_000 && powers > 5000,
            "{lit_lanes} lit, {powers} specular"
        );
    }
}
