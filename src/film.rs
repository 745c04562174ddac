//! The linear framebuffer the integrators fill: one value per pixel, before any
//! post-processing ([`crate::postprocess`]) or encoding ([`crate::output`]); and the
//! extra outputs ([`Aov`]s: depth, normal, albedo, coverage, object and material
//! ids) rendered in the same pass ([`Outputs`]).

pub use crate::integrators::aov::{Aov, UnknownAovError};

use crate::integrators::aov::AovPixel;
use crate::math::{Float, Vec3};

/// Linear per-pixel values, row 0 at the top: radiance in full mode, the distance in
/// every channel in depth mode (infinity on a miss), the unit normal in normal mode
/// (zero on a miss).
#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height` values, row by row.
    pub pixels: Vec<Vec3>,
}

/// The extra planes of a render, each `width * height` values row by row, present
/// when asked for ([`Aov`] says what each holds).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct AovPlanes {
    /// [`Aov::Depth`].
    pub depth: Option<Vec<Float>>,
    /// [`Aov::Normal`].
    pub normal: Option<Vec<Vec3>>,
    /// [`Aov::Albedo`].
    pub albedo: Option<Vec<Vec3>>,
    /// [`Aov::Alpha`].
    pub alpha: Option<Vec<Float>>,
    /// [`Aov::ObjectId`].
    pub object_id: Option<Vec<i32>>,
    /// [`Aov::MaterialId`].
    pub material_id: Option<Vec<i32>>,
}

impl AovPlanes {
    /// Planes of `pixels` values for each of `aovs`, filled with what a miss holds.
    pub fn new(aovs: &[Aov], pixels: usize) -> AovPlanes {
        let has = |aov| aovs.contains(&aov);
        AovPlanes {
            depth: has(Aov::Depth).then(|| vec![Float::INFINITY; pixels]),
            normal: has(Aov::Normal).then(|| vec![Vec3::ZERO; pixels]),
            albedo: has(Aov::Albedo).then(|| vec![Vec3::ZERO; pixels]),
            alpha: has(Aov::Alpha).then(|| vec![0.0; pixels]),
            object_id: has(Aov::ObjectId).then(|| vec![-1; pixels]),
            material_id: has(Aov::MaterialId).then(|| vec![-1; pixels]),
        }
    }

    /// Sets pixel `i` of every plane held to `pixel`'s value.
    pub fn set(&mut self, i: usize, pixel: &AovPixel) {
        if let Some(plane) = &mut self.depth {
            plane[i] = pixel.depth;
        }
        if let Some(plane) = &mut self.alpha {
            plane[i] = pixel.alpha;
        }
        if let Some(plane) = &mut self.normal {
            plane[i] = pixel.normal;
        }
        if let Some(plane) = &mut self.albedo {
            plane[i] = pixel.albedo;
        }
        if let Some(plane) = &mut self.object_id {
            plane[i] = pixel.object;
        }
        if let Some(plane) = &mut self.material_id {
            plane[i] = pixel.material;
        }
    }

    /// The outputs held, in [`Aov::ALL`]'s order.
    pub fn aovs(&self) -> Vec<Aov> {
        Aov::ALL
            .into_iter()
            .filter(|&aov| match aov {
                Aov::Depth => self.depth.is_some(),
                Aov::Normal => self.normal.is_some(),
                Aov::Albedo => self.albedo.is_some(),
                Aov::Alpha => self.alpha.is_some(),
                Aov::ObjectId => self.object_id.is_some(),
                Aov::MaterialId => self.material_id.is_some(),
            })
            .collect()
    }
}

/// What a render gives: the colour [`Film`] and the [`AovPlanes`] asked for, of the
/// same size.
#[derive(Clone, Debug, PartialEq)]
pub struct Outputs {
    /// The colour (or the depth or normal of those modes), linear.
    pub film: Film,
    /// The extra outputs asked for.
    pub aovs: AovPlanes,
}
