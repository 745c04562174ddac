//! Area lights for path mode: every triangle or sphere whose material has `Ke != 0`
//! emits radiance `Ke`, times its `map_Ke` (glTF: emissive texture) at the point. A
//! triangle emits on the side its winding faces (normal `(p1 - p0) x (p2 - p0)`), a
//! sphere outwards.
//!
//! One emitter is chosen per light sample in proportion to its power through an alias
//! table, then a point uniformly on it: the cost of a sample does not grow with the
//! number of emitters. The power of an emitter is its area times its material's
//! *weight*: the mean of `Ke`, times the mean of the emission map over its whole image
//! when there is one (a mostly dark map draws few samples). So the density of a point
//! per unit area, `weight / total power`, depends on the material alone, which is what
//! lets a path that hits an emitter by chance weigh itself against light sampling
//! knowing only the material it hit ([`AreaLights::pdf`]). A sampled point's radiance
//! is evaluated as a camera ray's hit evaluates it, map and alpha cutout included, so
//! that light sampling and scattering estimate the same light.

pub mod environment;

use std::f32::consts::PI;

use crate::material::{Cutout, Material, MaterialId};
use crate::math::{Float, Vec2, Vec3};
use crate::textures::{Encoding, TextureMap};

/// The shape of one emitter.
#[derive(Clone, Copy, Debug, PartialEq)]
enum EmitterShape {
    /// Corner `p0` and edges `p1 - p0`, `p2 - p0`; `normal` is unit, on the winding
    /// side.
    Triangle {
        p0: Vec3,
        e1: Vec3,
        e2: Vec3,
        normal: Vec3,
    },
    Sphere {
        center: Vec3,
        radius: Float,
    },
}

/// One emitting primitive.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Emitter {
    shape: EmitterShape,
    /// Its material, an index into [`AreaLights::materials`].
    material: u32,
    /// Texture coordinates of a triangle's corners (zero for spheres, and where the
    /// triangle has none, as hits see them).
    uv: [Vec2; 3],
}

/// What light sampling needs of an emitting material.
#[derive(Clone, Debug, PartialEq)]
struct EmitterMaterial {
    /// `Ke`.
    emission: Vec3,
    /// `map_Ke`, which multiplies `Ke`.
    map: Option<TextureMap>,
    /// Where the surface is cut out (and emits nothing).
    cutout: Option<Cutout>,
    /// Power per unit area: `mean(Ke)` times the map's mean, 0 for materials that do
    /// not emit.
    weight: Float,
}

impl EmitterMaterial {
    fn new(material: &Material) -> EmitterMaterial {
        let maps = material.maps.as_deref();
        let map = maps.and_then(|m| m.emission.clone());
        let mut weight = mean(material.emission);
        if let Some(map) = &map {
            weight *= mean(map.mean_colour(Encoding::Srgb)).max(0.0);
        }
        if !(weight > 0.0 && weight.is_finite() && material.emission.is_finite()) {
            weight = 0.0;
        }
        EmitterMaterial {
            emission: material.emission,
            map,
            cutout: maps.and_then(|m| m.cutout.clone()),
            weight,
        }
    }

    /// Radiance at texture coordinates `uv`, exactly as [`Material::at`] gives it to a
    /// hit; `None` where the surface is cut out.
    #[inline]
    fn radiance(&self, uv: Vec2) -> Option<Vec3> {
        let mut radiance = self.emission;
        if let Some(cutout) = &self.cutout {
            // A blended emitter is hit by a fraction alpha of the rays meeting it:
            // its light samples carry that fraction.
            let coverage = cutout.coverage(uv);
            if coverage <= 0.0 {
                return None;
            }
            radiance *= coverage;
        }
        if let Some(map) = &self.map {
            radiance *= map.colour(uv, Encoding::Srgb);
        }
        Some(radiance)
    }
}

/// A point chosen on a light, seen from a shading point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSample {
    /// The point on the light.
    pub point: Vec3,
    /// Unit direction from the shading point to `point`.
    pub direction: Vec3,
    /// Distance from the shading point to `point`.
    pub distance: Float,
    /// Radiance leaving `point` towards the shading point (for a point light, the
    /// irradiance it gives: `I / d^2`).
    pub radiance: Vec3,
    /// Density of `direction` in solid angle (for a point light, the probability of
    /// choosing it).
    pub pdf: Float,
    /// Whether the light is a point, which no scattered ray can hit: its sample is
    /// not weighed against scattering.
    pub delta: bool,
}

/// The scene's emitting primitives and the table that picks one by power.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AreaLights {
    emitters: Vec<Emitter>,
    /// Every material of the scene, by [`MaterialId`] (weight 0 if it does not emit).
    materials: Vec<EmitterMaterial>,
    /// Vose's alias table: slot `i` keeps emitter `i` with probability
    /// `threshold[i]`, else takes `alias[i]`.
    threshold: Vec<Float>,
    alias: Vec<u32>,
    /// Sum over emitters of area times weight.
    total_power: Float,
}

/// Collects emitters for [`AreaLights`].
#[derive(Clone, Debug, Default)]
pub struct AreaLightsBuilder {
    emitters: Vec<Emitter>,
    materials: Vec<EmitterMaterial>,
}

impl AreaLightsBuilder {
    /// A builder for primitives of `materials` (indexed by [`MaterialId`]).
    pub fn new(materials: &[Material]) -> AreaLightsBuilder {
        AreaLightsBuilder {
            emitters: Vec::new(),
            materials: materials.iter().map(EmitterMaterial::new).collect(),
        }
    }

    /// Whether some material emits.
    pub fn any_emits(&self) -> bool {
        self.materials.iter().any(|m| m.weight > 0.0)
    }

    /// Whether shapes of `material` emit (and would be kept by
    /// [`AreaLightsBuilder::triangle`]).
    pub fn emits(&self, material: MaterialId) -> bool {
        (self.materials.get(material.0 as usize)).is_some_and(|m| m.weight > 0.0)
    }

    /// Adds the triangle `p0 p1 p2` with texture coordinates `uv` at its corners, if
    /// its material emits and it has an area.
    pub fn triangle(&mut self, [p0, p1, p2]: [Vec3; 3], uv: [Vec2; 3], material: MaterialId) {
        let (e1, e2) = (p1 - p0, p2 - p0);
        if let Some(normal) = e1.cross(e2).try_normalize() {
            self.push(EmitterShape::Triangle { p0, e1, e2, normal }, uv, material);
        }
    }

    /// Adds the sphere, emitting outwards, if its material emits.
    pub fn sphere(&mut self, center: Vec3, radius: Float, material: MaterialId) {
        if radius > 0.0 {
            self.push(
                EmitterShape::Sphere { center, radius },
                [Vec2::ZERO; 3],
                material,
            );
        }
    }

    fn push(&mut self, shape: EmitterShape, uv: [Vec2; 3], material: MaterialId) {
        let emits = self
            .materials
            .get(material.0 as usize)
            .is_some_and(|m| m.weight > 0.0);
        if emits {
            self.emitters.push(Emitter {
                shape,
                material: material.0,
                uv,
            });
        }
    }

    /// The lights, ready to sample.
    pub fn build(self) -> AreaLights {
        let powers: Vec<f64> = self
            .emitters
            .iter()
            .map(|e| {
                f64::from(area(&e.shape)) * f64::from(self.materials[e.material as usize].weight)
            })
            .collect();
        let total: f64 = powers.iter().sum();
        if !(total > 0.0 && total.is_finite()) {
            return AreaLights::default();
        }
        let (threshold, alias) = alias_table(&powers, total);
        AreaLights {
            emitters: self.emitters,
            materials: self.materials,
            threshold,
            alias,
            total_power: total as Float,
        }
    }
}

impl AreaLights {
    /// Sum over emitters of area times `mean(Ke)` (times the map's mean): their
    /// power over `pi`.
    pub fn total_power(&self) -> Float {
        self.total_power
    }

    /// Whether there is no emitter.
    pub fn is_empty(&self) -> bool {
        self.emitters.is_empty()
    }

    /// Number of emitting primitives.
    pub fn len(&self) -> usize {
        self.emitters.len()
    }

    /// A point on some emitter as seen from `from`: the emitter by `u_pick`, the
    /// point on it by `u`. `None` when the point faces away from `from`. Inlined, so
    /// that path mode reads the sample from registers rather than from a returned
    /// struct (whose reload would wait for store forwarding).
    #[inline(always)]
    pub fn sample(&self, from: Vec3, u_pick: Float, u: Vec2) -> Option<LightSample> {
        if self.emitters.is_empty() {
            return None;
        }
        let slots = self.emitters.len();
        let scaled = u_pick * slots as Float;
        let slot = (scaled as usize).min(slots - 1);
        let keep = scaled - (slot as Float) < self.threshold[slot];
        let emitter = &self.emitters[if keep {
            slot
        } else {
            self.alias[slot] as usize
        }];
        let (point, normal, uv) = match emitter.shape {
            EmitterShape::Triangle { p0, e1, e2, normal } => {
                // Uniform on the triangle (Shirley's square-root mapping).
                let s = u.x.sqrt();
                let (b1, b2) = (1.0 - s, u.y * s);
                // Interpolated as `Scene` interpolates a hit's.
                let [t0, t1, t2] = emitter.uv;
                let uv = t0 * (1.0 - b1 - b2) + t1 * b1 + t2 * b2;
                (p0 + e1 * b1 + e2 * b2, normal, uv)
            }
            EmitterShape::Sphere { center, radius } => {
                let z = 1.0 - 2.0 * u.x;
                let r = (1.0 - z * z).max(0.0).sqrt();
                let phi = 2.0 * PI * u.y;
                let normal = Vec3::new(r * phi.cos(), r * phi.sin(), z);
                (center + normal * radius, normal, Vec2::ZERO)
            }
        };
        let to_light = point - from;
        let distance_squared = to_light.length_squared();
        let distance = distance_squared.sqrt();
        // Zero (the shading point is on the light) or NaN.
        if distance.is_nan() || distance <= 0.0 {
            return None;
        }
        let direction = to_light / distance;
        let cos_light = -direction.dot(normal);
        if cos_light <= 0.0 {
            return None;
        }
        let material = &self.materials[emitter.material as usize];
        let radiance = material.radiance(uv)?;
        let pdf = material.weight / self.total_power * distance_squared / cos_light;
        Some(LightSample {
            point,
            direction,
            distance,
            radiance,
            pdf,
            delta: false,
        })
    }

    /// The solid-angle density with which [`AreaLights::sample`] from `from` picks
    /// the point `point` of an emitter of material `material` whose surface there
    /// makes the cosine `cos_light` with the direction back to `from`.
    #[inline]
    pub fn pdf(&self, material: MaterialId, from: Vec3, point: Vec3, cos_light: Float) -> Float {
        if cos_light <= 0.0 || self.total_power <= 0.0 {
            return 0.0;
        }
        // Density per unit area: every emitter of the material gets its area's share
        // of the material's power.
        let weight = self
            .materials
            .get(material.0 as usize)
            .map_or(0.0, |m| m.weight);
        weight / self.total_power * (point - from).length_squared() / cos_light
    }
}

#[inline]
fn mean(v: Vec3) -> Float {
    (v.x + v.y + v.z) / 3.0
}

fn area(shape: &EmitterShape) -> Float {
    match *shape {
        EmitterShape::Triangle { e1, e2, .. } => 0.5 * e1.cross(e2).length(),
        EmitterShape::Sphere { radius, .. } => 4.0 * PI * radius * radius,
    }
}

/// Vose's alias method: `threshold[i]` and `alias[i]` such that picking a slot
/// uniformly, then keeping it with probability `threshold[i]` or else taking
/// `alias[i]`, picks `i` with probability `weights[i] / total`.
fn alias_table(weights: &[f64], total: f64) -> (Vec<Float>, Vec<u32>) {
    let n = weights.len();
    let mut scaled: Vec<f64> = weights.iter().map(|w| w * n as f64 / total).collect();
    let mut alias: Vec<u32> = (0..n as u32).collect();
    let (mut small, mut large): (Vec<usize>, Vec<usize>) = (0..n).partition(|&i| scaled[i] < 1.0);
    while let (Some(s), Some(&l)) = (small.pop(), large.last()) {
        alias[s] = l as u32;
        scaled[l] -= 1.0 - scaled[s];
        if scaled[l] < 1.0 {
            large.pop();
            small.push(l);
        }
    }
    // What is left is 1 up to rounding.
    for i in small.into_iter().chain(large) {
        scaled[i] = 1.0;
    }
    (scaled.into_iter().map(|t| t as Float).collect(), alias)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Materials emitting `Ke` = each of `emissions`, in order.
    fn emitting(emissions: &[Vec3]) -> Vec<Material> {
        emissions
            .iter()
            .map(|&emission| Material {
                emission,
                ..Material::named("light")
            })
            .collect()
    }

    #[test]
    fn emitters_are_picked_in_proportion_to_power() {
        let materials = emitting(&[Vec3::splat(1.0), Vec3::splat(3.0), Vec3::ZERO]);
        let mut lights = AreaLightsBuilder::new(&materials);
        let quad = |x: Float| {
            [
                Vec3::new(x, 0.0, 0.0),
                Vec3::new(x + 1.0, 0.0, 0.0),
                Vec3::new(x, 0.0, 1.0),
            ]
        };
        let uv = [Vec2::ZERO; 3];
        lights.triangle(quad(0.0), uv, MaterialId(0));
        lights.triangle(quad(10.0), uv, MaterialId(1));
        lights.triangle(quad(20.0), uv, MaterialId(2)); // emits nothing: left out
        let lights = lights.build();
        assert_eq!(lights.len(), 2);
        let from = Vec3::new(5.0, -5.0, 0.5);
        let n = 10_000;
        let mut bright = 0;
        for i in 0..n {
            let u = (i as Float + 0.5) / n as Float;
            let s = lights.sample(from, u, Vec2::new(0.3, 0.3));
            // Both triangles face -y, towards `from`.
            bright += usize::from(s.expect("visible").point.x > 5.0);
        }
        let share = bright as Float / n as Float;
        assert!((share - 0.75).abs() < 0.01, "{share}");
    }

    #[test]
    fn the_sampled_pdf_equals_the_pdf_of_the_point_and_integrates_to_one() {
        let materials = emitting(&[Vec3::new(1.0, 2.0, 3.0), Vec3::splat(4.0)]);
        let mut lights = AreaLightsBuilder::new(&materials);
        // Facing -y (winding), seen from below.
        lights.triangle(
            [
                Vec3::new(0.0, 1.0, 0.0),
                Vec3::new(0.0, 1.0, 1.0),
                Vec3::new(1.0, 1.0, 0.0),
            ],
            [Vec2::ZERO; 3],
            MaterialId(0),
        );
        lights.sphere(Vec3::new(0.0, 3.0, 0.0), 0.5, MaterialId(1));
        let lights = lights.build();
        let from = Vec3::new(0.2, 0.0, 0.1);
        let mut inverse_sum = 0.0f64;
        let n = 64;
        for i in 0..n * n {
            let u = Vec2::new(
                ((i % n) as Float + 0.5) / n as Float,
                ((i / n) as Float + 0.5) / n as Float,
            );
            for pick in [0.1, 0.9] {
                if let Some(s) = lights.sample(from, pick, u) {
                    let (cos_light, material) = if s.point.y < 1.5 {
                        (-s.direction.y, MaterialId(0))
                    } else {
                        let normal = (s.point - Vec3::new(0.0, 3.0, 0.0)) / 0.5;
                        (-s.direction.dot(normal), MaterialId(1))
                    };
                    let pdf = lights.pdf(material, from, s.point, cos_light);
                    assert!((pdf - s.pdf).abs() <= 1e-3 * s.pdf, "{pdf} vs {}", s.pdf);
                    inverse_sum += 1.0 / f64::from(s.pdf);
                }
            }
        }
        // Summing 1/pdf estimates the solid angle the lights cover from `from`: finite and positive.
        assert!(inverse_sum > 0.0 && inverse_sum.is_finite());
    }

    #[test]
    fn emission_maps_weigh_the_pick_and_give_the_radiance_of_each_point() {
        use crate::material::MaterialMaps;
        use crate::textures::Texture;
        // A map black on its left half and white on its right (mean 1/2, linear),
        // clamped, on the second of two equal triangles of `Ke 1`; the third material
        // is cut out everywhere.
        let texture = Texture::from_u8("halves.png".into(), 2, 1, 1, vec![0, 255]).unwrap();
        let mut map = TextureMap::new(std::sync::Arc::new(texture));
        map.options.wrap_u = crate::textures::Wrap::Clamp;
        let mut materials = emitting(&[Vec3::ONE, Vec3::ONE, Vec3::ONE]);
        materials[1].maps = Some(Box::new(MaterialMaps {
            emission: Some(map),
            ..MaterialMaps::default()
        }));
        materials[2].maps = Some(Box::new(MaterialMaps {
            cutout: Some(Cutout {
                map: None,
                factor: 0.0,
                cutoff: 0.5,
                blend: false,
            }),
            ..MaterialMaps::default()
        }));
        let mut lights = AreaLightsBuilder::new(&materials);
        let corners = |x: Float| {
            [
                Vec3::new(x, 0.0, 0.0),
                Vec3::new(x + 1.0, 0.0, 0.0),
                Vec3::new(x, 0.0, 1.0),
            ]
        };
        // u runs along x.
        let uv = [Vec2::ZERO, Vec2::X, Vec2::ZERO];
        lights.triangle(corners(0.0), uv, MaterialId(0));
        lights.triangle(corners(10.0), uv, MaterialId(1));
        let lights = lights.build();
        let from = Vec3::new(5.0, -5.0, 0.5);
        let (n, mut textured) = (3000, 0);
        for i in 0..n {
            let u_pick = (i as Float + 0.5) / n as Float;
            let u = Vec2::new(((i * 7) % n) as Float / n as Float, 0.5);
            let s = lights.sample(from, u_pick, u).expect("visible");
            if s.point.x > 5.0 {
                textured += 1;
                let at = Vec2::new(s.point.x - 10.0, 0.0);
                let expected = materials[1].at(at).emission;
                assert!((s.radiance - expected).abs().max_element() < 1e-5, "{s:?}");
                // The triangles face -y: the cosine at the light is `direction.y`.
                let pdf = lights.pdf(MaterialId(1), from, s.point, s.direction.y);
                assert!((pdf - s.pdf).abs() <= 1e-4 * s.pdf);
            } else {
                assert_eq!(s.radiance, Vec3::ONE);
            }
        }
        // Power 1/2 against 1.
        let share = textured as Float / n as Float;
        assert!((share - 1.0 / 3.0).abs() < 0.01, "{share}");

        // A cut-out emitter is never sampled where a ray would pass through it.
        let mut lights = AreaLightsBuilder::new(&materials);
        lights.triangle(corners(0.0), uv, MaterialId(2));
        let lights = lights.build();
        assert_eq!(lights.len(), 1);
        assert_eq!(lights.sample(from, 0.5, Vec2::splat(0.5)), None);
    }

    #[test]
    fn alias_tables_reproduce_their_weights() {
        let weights = [1.0, 0.0, 5.0, 2.0, 2.0];
        let (threshold, alias) = alias_table(&weights, 10.0);
        let mut share = [0.0f64; 5];
        for (slot, (&t, &a)) in threshold.iter().zip(&alias).enumerate() {
            share[slot] += f64::from(t) / 5.0;
            share[a as usize] += (1.0 - f64::from(t)) / 5.0;
        }
        for (s, w) in share.iter().zip(weights) {
            assert!((s - w / 10.0).abs() < 1e-6, "{share:?}");
        }
    }
}
