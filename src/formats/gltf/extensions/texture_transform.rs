//! `KHR_texture_transform`, on every texture reference (core and extensions alike):
//! an offset, rotation and scale of the texture coordinates, and optionally another
//! `texCoord` (both read by `MaterialContext::texture`).

use crate::math::{Float, Vec2};

pub(in crate::formats::gltf) const NAME: &str = "KHR_texture_transform";

/// The transform of `KHR_texture_transform`'s `offset`, `rotation` and `scale` as
/// this renderer's [`TextureOptions`](crate::textures::TextureOptions) `scale`,
/// `rotation` and `offset`, or `None` when they are not finite.
pub(in crate::formats::gltf) fn texture_options(
    offset: [Float; 2],
    rotation: Float,
    scale: [Float; 2],
) -> Option<(Vec2, Vec2, Vec2)> {
    let options = texture_transform(offset, rotation, scale);
    [options.0, options.1, options.2]
        .iter()
        .all(|v| v.is_finite())
        .then_some(options)
}

/// `KHR_texture_transform`'s `offset`, `rotation` and `scale` as this renderer's
/// [`TextureOptions`] `scale`, `rotation` and `offset`.
///
/// glTF turns its coordinates `g` (`v` down the image) into `R S g + o`, where `R`
/// takes `(u, v)` to `(c u + s v, -s u + c v)` (`c`, `s`: cosine and sine of the
/// angle; the extension's example, the lower left quadrant turned, fixes the sign).
/// Ours are `r = F g` with `F(u, v) = (u, 1 - v)`: conjugating by `F` gives
/// `R' S r + o'` with `R'` the counter-clockwise turn by the same angle and
/// `o' = (o.x + s.y sin, 1 - o.y - s.y cos)`.
fn texture_transform(offset: [Float; 2], rotation: Float, scale: [Float; 2]) -> (Vec2, Vec2, Vec2) {
    let (sin, cos) = rotation.sin_cos();
    let offset = Vec2::new(offset[0] + scale[1] * sin, 1.0 - offset[1] - scale[1] * cos);
    (Vec2::from(scale), Vec2::new(cos, sin), offset)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::textures::TextureOptions;

    #[test]
    fn texture_transforms_read_the_image_where_gltf_says() {
        // glTF's own mapping, in its coordinates (v down).
        let gltf = |g: Vec2, o: [f32; 2], angle: f32, s: [f32; 2]| {
            let (sin, cos) = angle.sin_cos();
            let (x, y) = (g.x * s[0], g.y * s[1]);
            Vec2::new(cos * x + sin * y + o[0], -sin * x + cos * y + o[1])
        };
        let cases = [
            ([0.0, 1.0], std::f32::consts::FRAC_PI_2, [0.5, 0.5]),
            ([0.25, -0.5], 0.3, [2.0, -1.5]),
            ([0.0, 0.0], 0.0, [1.0, 1.0]),
        ];
        for (o, angle, s) in cases {
            let (scale, rotation, offset) = texture_transform(o, angle, s);
            let options = TextureOptions {
                scale,
                rotation,
                offset,
                ..TextureOptions::default()
            };
            for g in [Vec2::ZERO, Vec2::new(1.0, 0.0), Vec2::new(0.3, 0.8)] {
                let want = gltf(g, o, angle, s);
                // Ours: v up.
                let got = options.transform(Vec2::new(g.x, 1.0 - g.y));
                let want = Vec2::new(want.x, 1.0 - want.y);
                assert!((got - want).abs().max_element() < 1e-5, "{got} vs {want}");
            }
        }
        // The extension's example reads the lower left quadrant of the image: in our
        // coordinates u in 0..0.5, v in 0..0.5, for every point of the unit square.
        let (scale, rotation, offset) =
            texture_transform([0.0, 1.0], std::f32::consts::FRAC_PI_2, [0.5, 0.5]);
        let options = TextureOptions {
            scale,
            rotation,
            offset,
            ..TextureOptions::default()
        };
        for uv in [Vec2::ZERO, Vec2::ONE, Vec2::new(0.2, 0.9)] {
            let at = options.transform(uv);
            assert!(
                (-1e-6..=0.5 + 1e-6).contains(&at.x) && (-1e-6..=0.5 + 1e-6).contains(&at.y),
                "{uv} -> {at}"
            );
        }
    }
}
