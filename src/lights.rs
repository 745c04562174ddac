//! Area lights for path mode: every triangle or sphere whose material has `Ke != 0`
//! emits radiance `Ke`. A triangle emits on the side its winding faces (normal
//! `(p1 - p0) x (p2 - p0)`), a sphere outwards.
//!
//! One emitter is chosen per light sample in proportion to its power (area times the
//! mean of `Ke`) through an alias table, then a point uniformly on it: the cost of a
//! sample does not grow with the number of emitters, and the density of a point per
//! unit area is the same `mean(Ke) / total power` on every emitter, which is what
//! lets a path that hits an emitter by chance weigh itself against light sampling
//! without knowing which emitter it hit ([`AreaLights::pdf`]).

use std::f32::consts::PI;

use crate::math::{Float, Vec2, Vec3};

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
    radiance: Vec3,
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
    /// Radiance leaving `point` towards the shading point.
    pub radiance: Vec3,
    /// Density of `direction` in solid angle.
    pub pdf: Float,
}

/// The scene's emitting primitives and the table that picks one by power.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AreaLights {
    emitters: Vec<Emitter>,
    /// Vose's alias table: slot `i` keeps emitter `i` with probability
    /// `threshold[i]`, else takes `alias[i]`.
    threshold: Vec<Float>,
    alias: Vec<u32>,
    /// Sum over emitters of area times mean radiance.
    total_power: Float,
}

/// Collects emitters for [`AreaLights::new`].
#[derive(Clone, Debug, Default)]
pub struct AreaLightsBuilder {
    emitters: Vec<Emitter>,
}

impl AreaLightsBuilder {
    /// Adds the triangle `p0 p1 p2` emitting `radiance` (ignored if it has no area
    /// or emits nothing).
    pub fn triangle(&mut self, [p0, p1, p2]: [Vec3; 3], radiance: Vec3) {
        let (e1, e2) = (p1 - p0, p2 - p0);
        if let Some(normal) = e1.cross(e2).try_normalize() {
            self.push(EmitterShape::Triangle { p0, e1, e2, normal }, radiance);
        }
    }

    /// Adds the sphere emitting `radiance` outwards.
    pub fn sphere(&mut self, center: Vec3, radius: Float, radiance: Vec3) {
        if radius > 0.0 {
            self.push(EmitterShape::Sphere { center, radius }, radiance);
        }
    }

    fn push(&mut self, shape: EmitterShape, radiance: Vec3) {
        if mean(radiance) > 0.0 && radiance.is_finite() {
            self.emitters.push(Emitter { shape, radiance });
        }
    }

    /// The lights, ready to sample.
    pub fn build(self) -> AreaLights {
        AreaLights::new(self.emitters)
    }
}

impl AreaLights {
    fn new(emitters: Vec<Emitter>) -> AreaLights {
        let powers: Vec<f64> = emitters
            .iter()
            .map(|e| f64::from(area(&e.shape)) * f64::from(mean(e.radiance)))
            .collect();
        let total: f64 = powers.iter().sum();
        if !(total > 0.0 && total.is_finite()) {
            return AreaLights::default();
        }
        let (threshold, alias) = alias_table(&powers, total);
        AreaLights {
            emitters,
            threshold,
            alias,
            total_power: total as Float,
        }
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
        let (point, normal) = match emitter.shape {
            EmitterShape::Triangle { p0, e1, e2, normal } => {
                // Uniform on the triangle (Shirley's square-root mapping).
                let s = u.x.sqrt();
                let (b1, b2) = (1.0 - s, u.y * s);
                (p0 + e1 * b1 + e2 * b2, normal)
            }
            EmitterShape::Sphere { center, radius } => {
                let z = 1.0 - 2.0 * u.x;
                let r = (1.0 - z * z).max(0.0).sqrt();
                let phi = 2.0 * PI * u.y;
                let normal = Vec3::new(r * phi.cos(), r * phi.sin(), z);
                (center + normal * radius, normal)
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
        let pdf = self.pdf_area(emitter.radiance) * distance_squared / cos_light;
        Some(LightSample {
            point,
            direction,
            distance,
            radiance: emitter.radiance,
            pdf,
        })
    }

    /// The solid-angle density with which [`AreaLights::sample`] from `from` picks
    /// the point `point` of an emitter of radiance `radiance` whose surface there
    /// makes the cosine `cos_light` with the direction back to `from`.
    #[inline]
    pub fn pdf(&self, radiance: Vec3, from: Vec3, point: Vec3, cos_light: Float) -> Float {
        if cos_light <= 0.0 || self.total_power <= 0.0 {
            return 0.0;
        }
        self.pdf_area(radiance) * (point - from).length_squared() / cos_light
    }

    /// Density per unit area of any point of an emitter of radiance `radiance`: the
    /// emitter's share of the power over its area.
    #[inline]
    fn pdf_area(&self, radiance: Vec3) -> Float {
        mean(radiance) / self.total_power
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

    #[test]
    fn emitters_are_picked_in_proportion_to_power() {
        let mut lights = AreaLightsBuilder::default();
        let quad = |x: Float| {
            [
                Vec3::new(x, 0.0, 0.0),
                Vec3::new(x + 1.0, 0.0, 0.0),
                Vec3::new(x, 0.0, 1.0),
            ]
        };
        lights.triangle(quad(0.0), Vec3::splat(1.0));
        lights.triangle(quad(10.0), Vec3::splat(3.0));
        lights.triangle(quad(20.0), Vec3::ZERO); // emits nothing: left out
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
        let mut lights = AreaLightsBuilder::default();
        // Facing -y (winding), seen from below.
        lights.triangle(
            [
                Vec3::new(0.0, 1.0, 0.0),
                Vec3::new(0.0, 1.0, 1.0),
                Vec3::new(1.0, 1.0, 0.0),
            ],
            Vec3::new(1.0, 2.0, 3.0),
        );
        lights.sphere(Vec3::new(0.0, 3.0, 0.0), 0.5, Vec3::splat(4.0));
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
                    let cos_light = if s.point.y < 1.5 {
                        -s.direction.y
                    } else {
                        -s.direction.dot((s.point - Vec3::new(0.0, 3.0, 0.0)) / 0.5)
                    };
                    let pdf = lights.pdf(s.radiance, from, s.point, cos_light);
                    assert!((pdf - s.pdf).abs() <= 1e-3 * s.pdf, "{pdf} vs {}", s.pdf);
                    inverse_sum += 1.0 / f64::from(s.pdf);
                }
            }
        }
        // Summing 1/pdf estimates the solid angle the lights cover from `from`: finite and positive.
        assert!(inverse_sum > 0.0 && inverse_sum.is_finite());
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
