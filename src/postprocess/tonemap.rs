//! Path mode's tone map operators ([`ToneMap`]): linear Rec. 709 radiance, already
//! multiplied by the exposure, to display values in `[0, 1]` after the sRGB curve.
//! One function per operator, each written from its published reference:
//!
//! - `standard`: clamp to `[0, 1]` (what earlier versions did);
//! - `khronos-neutral`: Khronos' PBR Neutral (KhronosGroup/ToneMapping,
//!   `PBR_Neutral/pbrNeutral.glsl` and the specification in its README);
//! - `agx`: three.js's `AgXToneMapping` (after Filament and Blender: Rec. 2020 primaries,
//!   the inset matrix, a log2 encoding over -12.47393..4.026069 EV, the sixth-degree
//!   polynomial contrast curve, the outset matrix, a 2.2 power back to linear and back
//!   to Rec. 709), clamped;
//! - `aces`: three.js's `ACESFilmicToneMapping`, Stephen Hill's fit of the ACES RRT and
//!   ODT with its input and output matrices and three.js's 1/0.6 brightening, clamped.
//!
//! Every operator ends in the sRGB transfer curve, as three.js encodes its output.
//! Negative and NaN channels are taken as 0 first (the references assume
//! non-negative input).

use glam::Mat3;

use super::srgb;
use crate::math::{Float, Vec3};
pub use crate::options::ToneMap;

impl ToneMap {
    /// `v` (linear, after the exposure) as display values in `[0, 1]`, sRGB-encoded.
    #[inline]
    pub fn apply(self, v: Vec3) -> Vec3 {
        match self {
            ToneMap::Standard => v.clamp(Vec3::ZERO, Vec3::ONE).map(srgb),
            ToneMap::KhronosNeutral => khronos_neutral(non_negative(v)).map(srgb),
            ToneMap::Agx => agx(non_negative(v)).map(srgb),
            ToneMap::Aces => aces(non_negative(v)).map(srgb),
        }
    }
}

/// `v` with negative and NaN channels as 0.
#[inline]
fn non_negative(v: Vec3) -> Vec3 {
    v.to_array().map(|c| if c > 0.0 { c } else { 0.0 }).into()
}

/// Khronos PBR Neutral of a non-negative linear colour; the result lies in `[0, 1]`.
pub fn khronos_neutral(color: Vec3) -> Vec3 {
    const START_COMPRESSION: Float = 0.8 - 0.04;
    const DESATURATION: Float = 0.15;
    let x = color.min_element();
    let offset = if x < 0.08 { x - 6.25 * x * x } else { 0.04 };
    let color = color - Vec3::splat(offset);
    let peak = color.max_element();
    if peak < START_COMPRESSION {
        return color;
    }
    let d = 1.0 - START_COMPRESSION;
    let new_peak = 1.0 - d * d / (peak + d - START_COMPRESSION);
    let color = color * (new_peak / peak);
    let g = 1.0 - 1.0 / (DESATURATION * (peak - new_peak) + 1.0);
    color.lerp(Vec3::splat(new_peak), g)
}

/// Rec. 2020 to Rec. 709 primaries, linear (ITU-R BT.2407), as three.js writes it
/// (rows given, transposed into columns).
fn rec2020_to_rec709() -> Mat3 {
    Mat3::from_cols(
        Vec3::new(1.6605, -0.5876, -0.0728),
        Vec3::new(-0.1246, 1.1329, -0.0083),
        Vec3::new(-0.0182, -0.1006, 1.1187),
    )
    .transpose()
}

/// AgX's inset matrix (columns, as three.js's `mat3` of three `vec3`).
const AGX_INSET: [[Float; 3]; 3] = [
    [0.856_627_15, 0.137_318_97, 0.111_898_21],
    [0.095_121_24, 0.761_242, 0.076_799_42],
    [0.048_251_606, 0.101_439_04, 0.811_302_37],
];

/// The inverse of AgX's outset matrix (columns); three.js inverts it.
const AGX_OUTSET_INVERSE: [[Float; 3]; 3] = [
    [0.899_796_96, 0.111_420_99, 0.111_420_99],
    [0.087_199_62, 0.875_575_6, 0.087_199_62],
    [0.013_003_425, 0.013_003_425, 0.801_379_4],
];

/// AgX's log2 range in EV: `log2(2^-10 * 0.18)` to `log2(2^6.5 * 0.18)`.
const AGX_MIN_EV: Float = -12.473_93;
const AGX_MAX_EV: Float = 4.026_069;

/// The polynomial approximation of AgX's default contrast curve (iolite's minimal
/// AgX, as three.js uses it), of a value in `[0, 1]`.
#[inline]
fn agx_contrast(x: Float) -> Float {
    let x2 = x * x;
    let x4 = x2 * x2;
    15.5 * x4 * x2 - 40.14 * x4 * x + 31.96 * x4 - 6.868 * x2 * x + 0.4298 * x2 + 0.1191 * x
        - 0.00232
}

/// AgX of a non-negative linear Rec. 709 colour, as linear Rec. 709 in `[0, 1]`.
pub fn agx(color: Vec3) -> Vec3 {
    let to_709 = rec2020_to_rec709();
    let to_2020 = to_709.inverse();
    let inset = Mat3::from_cols_array_2d(&AGX_INSET);
    let outset = Mat3::from_cols_array_2d(&AGX_OUTSET_INVERSE).inverse();
    let v = (to_2020 * color).max(Vec3::ZERO);
    let v = inset * v;
    let v = v.max(Vec3::splat(1e-10)).to_array().map(|c| {
        let encoded = (c.log2() - AGX_MIN_EV) / (AGX_MAX_EV - AGX_MIN_EV);
        agx_contrast(encoded.clamp(0.0, 1.0))
    });
    let v = outset * Vec3::from(v);
    let v = v.max(Vec3::ZERO).powf(2.2);
    (to_709 * v).clamp(Vec3::ZERO, Vec3::ONE)
}

/// Stephen Hill's fit of the ACES RRT and ODT, per channel.
#[inline]
fn rrt_and_odt_fit(v: Float) -> Float {
    let a = v * (v + 0.024_578_6) - 0.000_090_537;
    let b = v * (0.983_729 * v + 0.432_951) + 0.238_081;
    a / b
}

/// three.js's ACES filmic tone map of a non-negative linear colour, as linear Rec. 709
/// in `[0, 1]`.
pub fn aces(color: Vec3) -> Vec3 {
    // sRGB => XYZ => D65_2_D60 => AP1 => RRT_SAT, columns.
    let input = Mat3::from_cols(
        Vec3::new(0.597_19, 0.076, 0.0284),
        Vec3::new(0.354_58, 0.908_34, 0.133_83),
        Vec3::new(0.048_23, 0.015_66, 0.837_77),
    );
    // ODT_SAT => XYZ => D60_2_D65 => sRGB, columns.
    let output = Mat3::from_cols(
        Vec3::new(1.604_75, -0.102_08, -0.003_27),
        Vec3::new(-0.531_08, 1.108_13, -0.072_76),
        Vec3::new(-0.073_67, -0.006_05, 1.076_02),
    );
    let v = input * (color / 0.6);
    let v = v.to_array().map(rrt_and_odt_fit);
    (output * Vec3::from(v)).clamp(Vec3::ZERO, Vec3::ONE)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Khronos' specification's guarantee: base colours in `[0.08, 0.8]` come out
    /// less 0.04, exactly; the brightest stays below 1; white stays grey.
    #[test]
    fn khronos_neutral_keeps_base_colours_and_compresses_highlights() {
        let c = Vec3::new(0.08, 0.5, 0.8);
        assert!(
            (khronos_neutral(c) - (c - Vec3::splat(0.04)))
                .abs()
                .max_element()
                < 1e-6
        );
        for peak in [1.0, 10.0, 1e4] {
            let out = khronos_neutral(Vec3::new(peak, peak * 0.5, 0.1));
            assert!(
                out.max_element() <= 1.0 && out.min_element() >= 0.0,
                "{out}"
            );
            let grey = khronos_neutral(Vec3::splat(peak));
            assert!((grey.x - grey.y).abs() < 1e-6 && (grey.y - grey.z).abs() < 1e-6);
        }
        assert_eq!(khronos_neutral(Vec3::ZERO), Vec3::ZERO);
    }

    /// AgX against values computed independently in f64 from three.js's published
    /// formula (its matrices as written there, inverted in f64).
    #[test]
    fn agx_matches_the_published_formula() {
        for (input, expected) in [
            (Vec3::splat(0.18), [0.214_524_3, 0.214_520_4, 0.214_514_5]),
            (Vec3::splat(1.0), [0.590_195_8, 0.590_161, 0.590_123_6]),
            (
                Vec3::new(2.0, 0.5, 0.1),
                [0.816_254_6, 0.453_823, 0.263_108_1],
            ),
            (Vec3::ZERO, [0.0, 0.0, 0.0]),
        ] {
            let got = agx(input);
            for (g, e) in got.to_array().iter().zip(expected) {
                assert!((g - e).abs() < 2e-5, "{input}: {got} against {expected:?}");
            }
        }
    }

    /// ACES against values computed independently in f64 from three.js's formula.
    #[test]
    fn aces_matches_the_published_formula() {
        for (input, expected) in [
            (Vec3::splat(0.18), [0.213_105_4, 0.213_105_4, 0.213_103_3]),
            (Vec3::splat(1.0), [0.763_397_4, 0.763_397_4, 0.763_389_8]),
            (
                Vec3::new(2.0, 0.5, 0.1),
                [0.982_303_9, 0.604_406_3, 0.224_429_2],
            ),
            (Vec3::ZERO, [0.0, 0.0, 0.0]),
        ] {
            let got = aces(input);
            for (g, e) in got.to_array().iter().zip(expected) {
                assert!((g - e).abs() < 2e-5, "{input}: {got} against {expected:?}");
            }
        }
    }

    #[test]
    fn standard_is_the_clamped_srgb_curve_and_names_round_trip() {
        let v = Vec3::new(-1.0, 0.5, 7.0);
        assert_eq!(
            ToneMap::Standard.apply(v),
            v.clamp(Vec3::ZERO, Vec3::ONE).map(srgb)
        );
        for (name, tonemap) in ToneMap::NAMES {
            assert_eq!(name.parse::<ToneMap>(), Ok(tonemap));
            assert_eq!(tonemap.name(), name);
        }
        assert!("filmic".parse::<ToneMap>().unwrap_err().contains("agx"));
        assert_eq!(ToneMap::default(), ToneMap::KhronosNeutral);
    }
}
