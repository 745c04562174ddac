//! Punctual lights: points, spots and directional lights, as glTF's
//! `KHR_lights_punctual` defines them, read from every format into one closed type.
//!
//! Units: a point or spot light's `intensity` is a luminous intensity (candela in
//! glTF), a directional light's an illuminance (lux). In path mode a point light of
//! intensity `I` at distance `d` gives the irradiance `I / d^2` (and a directional
//! light of `E` the irradiance `E cos`) in the units in which an emitter of emission
//! 1 has radiance 1. Full mode is SPEC's Phong model, whose point lights do not fall
//! off with distance: there a light adds `I * (Kd cos + Ks ...)` times its cone
//! attenuation and range window, with no `1 / d^2`.

use crate::math::{Float, Vec3};

/// What kind of light a [`Light`] is, with what that kind needs besides a position.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightKind {
    /// Shines equally in every direction from its position.
    Point,
    /// Shines from its position in a cone: fully within the inner cone, falling off
    /// smoothly to nothing at the outer cone ([`spot_attenuation`]).
    Spot {
        /// The cone's axis, the way the light shines (unit length).
        direction: Vec3,
        /// The cosine of the inner cone's half-angle.
        cos_inner: Float,
        /// The cosine of the outer cone's half-angle (at most `cos_inner`).
        cos_outer: Float,
    },
    /// Shines from infinitely far away; the position is not used.
    Directional {
        /// The way the light shines (unit length).
        direction: Vec3,
    },
}

/// A punctual light: SPEC's point light (`P` in OBJ) is [`Light::point`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    /// Position (not used by directional lights).
    pub position: Vec3,
    /// Intensity per channel (candela for point and spot lights, lux for directional
    /// ones); may exceed 1.
    pub intensity: Vec3,
    /// Point, spot or directional, with the kind's own values.
    pub kind: LightKind,
    /// Distance beyond which the light adds nothing (glTF's `range`), with the
    /// extension's recommended smooth window; `None`: no limit. Not used by
    /// directional lights.
    pub range: Option<Float>,
}

/// Where a light's light comes from at a point, and how much of its intensity
/// arrives there before distance falls it off.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Incident {
    /// Unit direction from the point towards the light.
    pub direction: Vec3,
    /// Distance to the light; infinite for a directional light.
    pub distance: Float,
    /// The spot cone's attenuation times the range window (1 for a point light with
    /// no range and for a directional light), in `(0, 1]`.
    pub falloff: Float,
}

impl Light {
    /// SPEC's point light.
    pub fn point(position: Vec3, intensity: Vec3) -> Light {
        Light {
            position,
            intensity,
            kind: LightKind::Point,
            range: None,
        }
    }

    /// Whether this is a point light with no range: SPEC's point light, which the
    /// integrators shade by their original code (bit for bit).
    #[inline]
    pub fn is_plain_point(&self) -> bool {
        matches!(self.kind, LightKind::Point) && self.range.is_none()
    }

    /// The light's direction, for spot and directional lights.
    pub fn direction(&self) -> Option<Vec3> {
        match self.kind {
            LightKind::Point => None,
            LightKind::Spot { direction, .. } | LightKind::Directional { direction } => {
                Some(direction)
            }
        }
    }

    /// Where this light's light comes from at `p`, and its falloff there (the spot's
    /// cone and the range window, not `1 / d^2`); `None` where it adds nothing: at
    /// the light's own position, outside a spot's outer cone, beyond the range.
    #[inline]
    pub fn incident(&self, p: Vec3) -> Option<Incident> {
        if let LightKind::Directional { direction } = self.kind {
            return Some(Incident {
                direction: -direction,
                distance: Float::INFINITY,
                falloff: 1.0,
            });
        }
        let to_light = self.position - p;
        let distance = to_light.length();
        if !distance.is_normal() {
            return None;
        }
        let direction = to_light / distance;
        let mut falloff = match self.range {
            Some(range) => range_window(distance, range),
            None => 1.0,
        };
        if let LightKind::Spot {
            direction: axis,
            cos_inner,
            cos_outer,
        } = self.kind
        {
            falloff *= spot_attenuation(axis.dot(-direction), cos_inner, cos_outer);
        }
        (falloff > 0.0).then_some(Incident {
            direction,
            distance,
            falloff,
        })
    }
}

/// `KHR_lights_punctual`'s spot attenuation at an angle whose cosine from the spot's
/// axis is `cos_theta`: `t = clamp(cos_theta * scale + offset, 0, 1)`, `t^2`, with
/// `scale = 1 / max(0.001, cos_inner - cos_outer)` and `offset = -cos_outer * scale`.
#[inline]
pub fn spot_attenuation(cos_theta: Float, cos_inner: Float, cos_outer: Float) -> Float {
    let scale = 1.0 / (cos_inner - cos_outer).max(0.001);
    let offset = -cos_outer * scale;
    let t = (cos_theta * scale + offset).clamp(0.0, 1.0);
    t * t
}

/// `KHR_lights_punctual`'s recommended range window, `clamp(1 - (d / range)^4, 0, 1)^2`
/// (the `1 / d^2` of that formula is the light's own falloff, applied apart).
#[inline]
pub fn range_window(distance: Float, range: Float) -> Float {
    let ratio = distance / range;
    let w = (1.0 - ratio * ratio * ratio * ratio).clamp(0.0, 1.0);
    w * w
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spot_attenuation_is_one_inside_zero_outside_smooth_between() {
        let (inner, outer) = (10.0_f32.to_radians().cos(), 30.0_f32.to_radians().cos());
        assert_eq!(spot_attenuation(1.0, inner, outer), 1.0);
        assert_eq!(
            spot_attenuation(5.0_f32.to_radians().cos(), inner, outer),
            1.0
        );
        assert_eq!(
            spot_attenuation(40.0_f32.to_radians().cos(), inner, outer),
            0.0
        );
        let c = 20.0_f32.to_radians().cos();
        let t = (c - outer) / (inner - outer);
        assert!((spot_attenuation(c, inner, outer) - t * t).abs() < 1e-5);
    }

    #[test]
    fn range_window_is_one_near_zero_beyond() {
        assert_eq!(range_window(0.0, 2.0), 1.0);
        assert_eq!(range_window(2.0, 2.0), 0.0);
        assert_eq!(range_window(3.0, 2.0), 0.0);
        assert!((range_window(1.0, 2.0) - (1.0 - 1.0 / 16.0_f32).powi(2)).abs() < 1e-6);
    }

    #[test]
    fn directional_light_comes_from_against_its_direction() {
        let light = Light {
            kind: LightKind::Directional {
                direction: Vec3::NEG_Y,
            },
            ..Light::point(Vec3::ZERO, Vec3::ONE)
        };
        let incident = light.incident(Vec3::new(5.0, -3.0, 2.0)).unwrap();
        assert_eq!(incident.direction, Vec3::Y);
        assert_eq!(incident.distance, Float::INFINITY);
        assert_eq!(incident.falloff, 1.0);
    }
}
