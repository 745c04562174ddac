//! The extra outputs of a pixel ([`Aov`]): what the camera rays of its
//! samples hit, traced again beside the colour's integrator, with the same camera
//! rays (so coverage matches the colour's samples exactly). Traced only for a render
//! that asks for outputs: others pay nothing.

use std::fmt;
use std::str::FromStr;

use super::TileContext;
use crate::bvh::PACKET_SIZE;
use crate::math::{Float, Ray, Vec3};
use crate::scene::{Hit, Scene};

/// An extra output of a render, beside the colour ("arbitrary output variable"),
/// rendered in the same pass from the camera rays of the colour's samples. Float
/// outputs are averaged over a pixel's samples; ids are those of the ray through the
/// pixel's centre.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Aov {
    /// z-depth: the distance of the hit along the camera's optical axis (not along
    /// the ray), averaged over the samples that hit; infinity where none did.
    Depth,
    /// The world-space unit shading normal facing the camera ray, averaged over the
    /// samples (a miss counts as zero).
    Normal,
    /// The surface's reflectance colour: `Kd`, or the base colour of a physically
    /// based material, textures applied; averaged over the samples (a miss counts as
    /// zero).
    Albedo,
    /// Coverage: the fraction of the pixel's camera rays that hit a shape.
    Alpha,
    /// The id of the object seen through the pixel centre ([`crate::Scene::object_names`]);
    /// -1 on a miss.
    ObjectId,
    /// The id of the material seen through the pixel centre (an index into
    /// [`crate::Scene::materials`]); -1 on a miss.
    MaterialId,
}

impl Aov {
    /// Every output, in the order of their layers in an OpenEXR file.
    pub const ALL: [Aov; 6] = [
        Aov::Depth,
        Aov::Normal,
        Aov::Albedo,
        Aov::Alpha,
        Aov::ObjectId,
        Aov::MaterialId,
    ];

    /// The output's name: `depth`, `normal`, `albedo`, `alpha`, `object_id`,
    /// `material_id` (the CLI's `--aovs` and the Python keyword take these).
    pub fn name(self) -> &'static str {
        match self {
            Aov::Depth => "depth",
            Aov::Normal => "normal",
            Aov::Albedo => "albedo",
            Aov::Alpha => "alpha",
            Aov::ObjectId => "object_id",
            Aov::MaterialId => "material_id",
        }
    }

    /// Parses a comma-separated list of names (`depth,normal`), each once.
    ///
    /// # Errors
    /// An unknown or repeated name, named in the message with the known ones.
    pub fn parse_list(list: &str) -> Result<Vec<Aov>, UnknownAovError> {
        let mut aovs = Vec::new();
        for name in list.split(',').map(str::trim) {
            let aov: Aov = name.parse()?;
            if aovs.contains(&aov) {
                return Err(UnknownAovError {
                    name: name.into(),
                    repeated: true,
                });
            }
            aovs.push(aov);
        }
        Ok(aovs)
    }
}

impl fmt::Display for Aov {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A name that is no [`Aov`]'s, or one given twice.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "{}: the outputs are depth, normal, albedo, alpha, object_id and material_id, each named once",
    if *repeated { format!("'{name}' is named twice") } else { format!("unknown output '{name}'") }
)]
pub struct UnknownAovError {
    /// The name given.
    pub name: String,
    /// Whether it was known but given twice.
    pub repeated: bool,
}

impl FromStr for Aov {
    type Err = UnknownAovError;

    fn from_str(name: &str) -> Result<Aov, UnknownAovError> {
        Aov::ALL
            .into_iter()
            .find(|aov| aov.name() == name)
            .ok_or_else(|| UnknownAovError {
                name: name.into(),
                repeated: false,
            })
    }
}

/// Which of the outputs a render asks for, as flags tested per pixel.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AovSet {
    /// Depth, normal, albedo or alpha: every sample's ray is traced.
    pub surfaces: bool,
    /// Object or material id: the ray through the pixel centre is traced.
    pub ids: bool,
    /// Albedo: the material is looked up at each hit.
    pub albedo: bool,
}

impl AovSet {
    /// The set of `aovs`.
    pub fn of(aovs: &[Aov]) -> AovSet {
        let has = |aov| aovs.contains(&aov);
        AovSet {
            surfaces: has(Aov::Depth) || has(Aov::Normal) || has(Aov::Albedo) || has(Aov::Alpha),
            ids: has(Aov::ObjectId) || has(Aov::MaterialId),
            albedo: has(Aov::Albedo),
        }
    }

    /// Whether any output is asked for.
    pub fn any(&self) -> bool {
        self.surfaces || self.ids
    }
}

/// Every extra output of one pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AovPixel {
    /// [`Aov::Depth`].
    pub depth: Float,
    /// [`Aov::Normal`].
    pub normal: Vec3,
    /// [`Aov::Albedo`].
    pub albedo: Vec3,
    /// [`Aov::Alpha`].
    pub alpha: Float,
    /// [`Aov::ObjectId`].
    pub object: i32,
    /// [`Aov::MaterialId`].
    pub material: i32,
}

impl AovPixel {
    /// What a pixel that sees nothing holds.
    pub const MISS: AovPixel = AovPixel {
        depth: Float::INFINITY,
        normal: Vec3::ZERO,
        albedo: Vec3::ZERO,
        alpha: 0.0,
        object: -1,
        material: -1,
    };
}

/// The outputs `set` asks for of the pixels of columns `left..left + width` of rows
/// `top..top + rows`, row by row, into `out`: [`aov_pixel`] of each, bit for bit; at
/// one sample per pixel through a pinhole, each 4x4 tile's camera rays are traced as
/// one packet ([`Scene::intersect_object_packet`]).
pub fn aov_band(
    context: &TileContext,
    (left, top, width, rows): (u32, u32, u32, u32),
    set: AovSet,
    out: &mut Vec<AovPixel>,
) {
    let start = out.len();
    out.resize(start + (width * rows) as usize, AovPixel::MISS);
    let out = &mut out[start..];
    if context.sampler.count() != 1 || !context.camera.is_pinhole() {
        for (i, pixel) in out.iter_mut().enumerate() {
            let (column, row) = (left + i as u32 % width, top + i as u32 / width);
            *pixel = aov_pixel(context, column, row, set);
        }
        return;
    }
    let forward = context.camera.forward();
    let mut rays = [Ray::new(Vec3::ZERO, Vec3::Z); PACKET_SIZE];
    let mut hits = [None; PACKET_SIZE];
    for tile_top in (top..top + rows).step_by(4) {
        let tile_rows = (top + rows - tile_top).min(4);
        for tile_left in (left..left + width).step_by(4) {
            let columns = (left + width - tile_left).min(4);
            let count = (columns * tile_rows) as usize;
            context
                .camera
                .tile_rays(tile_left, tile_top, columns, tile_rows, &mut rays);
            context
                .scene
                .intersect_object_packet(&rays[..count], &mut hits[..count]);
            for (k, (ray, hit)) in rays[..count].iter().zip(&hits[..count]).enumerate() {
                let (column, row) = (k as u32 % columns, k as u32 / columns);
                let i = ((tile_top - top + row) * width + tile_left - left + column) as usize;
                out[i] = one_hit(context.scene, ray, hit.as_ref(), forward, set);
            }
        }
    }
}

/// [`aov_pixel`] of a pixel whose one camera ray `ray` found `hit` (with its object).
fn one_hit(
    scene: &Scene,
    ray: &Ray,
    hit: Option<&(Hit, u32)>,
    forward: Vec3,
    set: AovSet,
) -> AovPixel {
    let Some((hit, object)) = hit else {
        return AovPixel::MISS;
    };
    let mut out = AovPixel::MISS;
    if set.ids {
        out.object = *object as i32;
        out.material = hit.material.0 as i32;
    }
    if set.surfaces {
        out.depth = hit.t * ray.dir.dot(forward);
        out.normal = hit.ns;
        out.alpha = 1.0;
        if set.albedo {
            out.albedo = albedo(scene, hit);
        }
    }
    out
}

/// The reflectance colour at `hit`: `Kd`, or a physically based material's base
/// colour, textures applied.
fn albedo(scene: &Scene, hit: &Hit) -> Vec3 {
    let material = &scene.materials[hit.material.0 as usize];
    match material.pbr_at_point(hit.uv, hit.colour) {
        Some(values) => values.base_color,
        None => material.at_point(hit.uv, hit.colour).diffuse,
    }
}

/// The outputs `set` asks for of pixel (`column`, `row`): its samples' camera rays are
/// those the colour's integrator traced ([`crate::PixelSampler::average`]'s positions
/// and [`crate::Camera::sample_ray`]); the ids are those of sample 0's ray through the
/// pixel centre (with one sample per pixel, the colour's own ray).
pub fn aov_pixel(context: &TileContext, column: u32, row: u32, set: AovSet) -> AovPixel {
    let TileContext {
        scene,
        camera,
        sampler,
        image_width,
    } = *context;
    let mut out = AovPixel::MISS;
    let pixel_index = row as u64 * image_width as u64 + column as u64;
    let (x0, y0) = (column as Float, row as Float);
    let forward = camera.forward();
    let count = sampler.count();
    // With one sample a pixel, sample 0's ray is the centre's: traced once for both.
    let mut centre_hit = None;
    if set.ids {
        let ray = camera.sample_ray(x0 + 0.5, y0 + 0.5, &sampler.sample(pixel_index, 0));
        if let Some((hit, object)) = scene.intersect_object(&ray) {
            out.object = object as i32;
            out.material = hit.material.0 as i32;
            centre_hit = Some(hit);
        }
    }
    if !set.surfaces {
        return out;
    }
    let (mut depth, mut normal, mut albedo, mut hits) = (0.0, Vec3::ZERO, Vec3::ZERO, 0u32);
    for sample in 0..count {
        let offset = sampler.offset(pixel_index, sample);
        let values = sampler.sample(pixel_index, sample);
        let ray = camera.sample_ray(x0 + offset.x, y0 + offset.y, &values);
        let hit = match (count, set.ids) {
            (1, true) => centre_hit,
            _ => scene.intersect(&ray),
        };
        let Some(hit) = hit else {
            continue;
        };
        hits += 1;
        depth += hit.t * ray.dir.dot(forward);
        normal += hit.ns;
        if set.albedo {
            albedo += self::albedo(scene, &hit);
        }
    }
    if hits > 0 {
        let n = count as Float;
        out.depth = depth / hits as Float;
        out.normal = normal / n;
        out.albedo = albedo / n;
        out.alpha = hits as Float / n;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Camera;
    use crate::sampler::PixelSampler;

    /// The packets of `aov_band` give exactly `aov_pixel`'s outputs, for a band
    /// whose edges cut the 4x4 tiles.
    #[test]
    fn packets_give_each_pixels_outputs() {
        let scene = crate::scene::packet_tests::generated_scene(60, true, 3);
        let (width, height) = (37, 23);
        let camera = Camera::new(
            Vec3::new(0.3, 1.2, 1.8),
            Vec3::new(0.0, 0.1, 0.0),
            55.0,
            width,
            height,
        );
        let sampler = PixelSampler::new(1, 0);
        let context = TileContext {
            scene: &scene,
            camera: &camera,
            sampler: &sampler,
            image_width: width,
        };
        let set = AovSet::of(&Aov::ALL);
        let (left, top, w, h) = (3, 2, 30, 19);
        let mut band = Vec::new();
        aov_band(&context, (left, top, w, h), set, &mut band);
        let (mut hits, mut misses) = (0, 0);
        for (i, got) in band.iter().enumerate() {
            let (column, row) = (left + i as u32 % w, top + i as u32 / w);
            let expected = aov_pixel(&context, column, row, set);
            assert_eq!(
                format!("{got:?}"),
                format!("{expected:?}"),
                "pixel ({column}, {row})"
            );
            if got.object >= 0 {
                hits += 1;
            } else {
                misses += 1;
            }
        }
        assert!(hits > 100 && misses > 10, "{hits} hits, {misses} misses");
    }
}
