//! The extra outputs of a pixel ([`Aov`]): what the camera rays of its samples hit,
//! taken from the hits the colour's integrator finds for them ([`BandAovs`],
//! [`PixelAovs`]), so each camera ray is traced once. Filled only for a render that
//! asks for outputs: others pay one predictable branch per camera ray.

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
    /// Depth, normal, albedo or alpha: every sample's hit counts.
    pub surfaces: bool,
    /// Object or material id: the hit through the pixel centre names them.
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

impl AovPixel {
    /// Where a pixel's sums start, before [`AovPixel::finish`]: nothing hit yet.
    const EMPTY: AovPixel = AovPixel {
        depth: 0.0,
        normal: Vec3::ZERO,
        albedo: Vec3::ZERO,
        alpha: 0.0,
        object: -1,
        material: -1,
    };

    /// Adds camera ray `ray`'s hit `hit` to the sums of the float outputs (`alpha`
    /// counts the hits until [`AovPixel::finish`]).
    #[inline]
    fn add(&mut self, scene: &Scene, ray: &Ray, hit: &Hit, forward: Vec3, set: AovSet) {
        self.depth += hit.t * ray.dir.dot(forward);
        self.normal += hit.ns;
        self.alpha += 1.0;
        if set.albedo {
            self.albedo += albedo(scene, hit);
        }
    }

    /// The sums of `samples` camera rays made means: depth over the rays that hit
    /// (infinity if none did), the others over all of them (a miss counts as zero).
    fn finish(&mut self, samples: u32) {
        let hits = self.alpha;
        if hits == 0.0 {
            self.depth = Float::INFINITY;
            return;
        }
        let n = samples as Float;
        self.depth /= hits;
        self.normal /= n;
        self.albedo /= n;
        self.alpha = hits / n;
    }
}

/// The extra outputs of a band of pixels, filled from the hits of the camera rays
/// the colour's integrator traces ([`PixelAovs::intersect`],
/// [`BandAovs::intersect_packet`]): one pass, no ray traced twice. Ids come from
/// those hits at one sample per pixel, whose ray goes through the pixel centre;
/// with more, no sample goes through the centre (they are jittered in strata), so
/// [`BandAovs::finish`] traces a ray of its own through each pixel centre, for the
/// ids alone.
#[derive(Debug)]
pub struct BandAovs<'a> {
    set: AovSet,
    /// Whether the ids come from the integrator's hits (one sample per pixel).
    ids_from_hits: bool,
    forward: Vec3,
    /// One per pixel of the band, row by row; empty when no output is asked for.
    pixels: &'a mut [AovPixel],
}

impl<'a> BandAovs<'a> {
    /// No outputs: the integrator's queries are the scene's own.
    pub fn none() -> BandAovs<'a> {
        BandAovs {
            set: AovSet::default(),
            ids_from_hits: false,
            forward: Vec3::ZERO,
            pixels: &mut [],
        }
    }

    /// The outputs `set` of a band of `pixels.len()` pixels rendered in `context`,
    /// written into `pixels` (whatever they held).
    pub fn new(context: &TileContext, set: AovSet, pixels: &'a mut [AovPixel]) -> BandAovs<'a> {
        pixels.fill(AovPixel::EMPTY);
        BandAovs {
            set,
            ids_from_hits: set.ids && context.sampler.count() == 1,
            forward: context.camera.forward(),
            pixels,
        }
    }

    /// Whether any output is asked for.
    #[inline]
    pub fn wanted(&self) -> bool {
        !self.pixels.is_empty()
    }

    /// The outputs of the band's pixel `i` (row by row).
    #[inline]
    pub fn pixel(&mut self, i: usize) -> PixelAovs<'_> {
        PixelAovs {
            set: self.set,
            ids_from_hits: self.ids_from_hits,
            forward: self.forward,
            out: self.pixels.get_mut(i),
        }
    }

    /// The closest hits of a tile's camera rays `rays` (coherent, at most a packet)
    /// into `hits`, traced as one packet ([`Scene::intersect_packet`], or
    /// [`Scene::intersect_object_packet`] when ids are asked for: bit for bit the same
    /// hits), and added to the outputs of the band's pixels `pixel(k)` of each ray `k`.
    #[inline]
    pub fn intersect_packet(
        &mut self,
        scene: &Scene,
        rays: &[Ray],
        hits: &mut [Option<Hit>],
        pixel: impl Fn(usize) -> usize,
    ) {
        if !self.wanted() {
            scene.intersect_packet(rays, hits);
            return;
        }
        if self.ids_from_hits {
            let mut found = [None; PACKET_SIZE];
            let found = &mut found[..rays.len()];
            scene.intersect_object_packet(rays, found);
            for (k, (hit, found)) in hits.iter_mut().zip(found.iter()).enumerate() {
                *hit = found.map(|(hit, _)| hit);
                self.pixel(pixel(k)).record(scene, &rays[k], found.as_ref());
            }
            return;
        }
        scene.intersect_packet(rays, hits);
        for (k, hit) in hits.iter().enumerate() {
            if let Some(hit) = hit {
                let out = &mut self.pixels[pixel(k)];
                out.add(scene, &rays[k], hit, self.forward, self.set);
            }
        }
    }
}

/// Makes the sums a [`BandAovs`] of `set` added up in `pixels` (the pixels of
/// columns `left..left + width` of rows `top..`, row by row) means of `context`'s
/// samples per pixel, and sets their ids by a ray of their own through each pixel
/// centre where the integrator's rays did not go through it.
pub fn finish_band(
    context: &TileContext,
    set: AovSet,
    pixels: &mut [AovPixel],
    (left, top, width): (u32, u32, u32),
) {
    let count = context.sampler.count();
    let centre_ids = set.ids && count != 1;
    for (i, out) in pixels.iter_mut().enumerate() {
        out.finish(count);
        if centre_ids {
            let (column, row) = (left + i as u32 % width, top + i as u32 / width);
            (out.object, out.material) = centre_ids_of(context, column, row);
        }
    }
}

/// The extra outputs of one pixel while its camera rays are traced: where an
/// integrator's [`PixelAovs::intersect`] puts what each ray hits.
#[derive(Debug)]
pub struct PixelAovs<'a> {
    set: AovSet,
    ids_from_hits: bool,
    forward: Vec3,
    /// `None` when no output is asked for.
    out: Option<&'a mut AovPixel>,
}

impl PixelAovs<'_> {
    /// No outputs: [`PixelAovs::intersect`] is [`Scene::intersect`].
    pub fn none() -> PixelAovs<'static> {
        PixelAovs {
            set: AovSet::default(),
            ids_from_hits: false,
            forward: Vec3::ZERO,
            out: None,
        }
    }

    /// Whether any output is asked for.
    #[inline]
    pub fn wanted(&self) -> bool {
        self.out.is_some()
    }

    /// The closest hit of the pixel's camera ray `ray` ([`Scene::intersect`], or
    /// [`Scene::intersect_object`] when its ids are asked for: the same hit), added
    /// to the pixel's outputs.
    #[inline]
    pub fn intersect(&mut self, scene: &Scene, ray: &Ray) -> Option<Hit> {
        if self.out.is_none() {
            return scene.intersect(ray);
        }
        if self.ids_from_hits {
            let found = scene.intersect_object(ray);
            self.record(scene, ray, found.as_ref());
            return found.map(|(hit, _)| hit);
        }
        let hit = scene.intersect(ray);
        if let (Some(out), Some(hit)) = (&mut self.out, &hit) {
            out.add(scene, ray, hit, self.forward, self.set);
        }
        hit
    }

    /// Adds `found`, the hit of `ray` with its object, to the outputs, the ids with it.
    #[inline]
    fn record(&mut self, scene: &Scene, ray: &Ray, found: Option<&(Hit, u32)>) {
        let (Some(out), Some((hit, object))) = (&mut self.out, found) else {
            return;
        };
        out.add(scene, ray, hit, self.forward, self.set);
        out.object = *object as i32;
        out.material = hit.material.0 as i32;
    }
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

/// The object and material ids of pixel (`column`, `row`): those of the ray through
/// its centre (with sample 0's lens position); -1 on a miss.
fn centre_ids_of(context: &TileContext, column: u32, row: u32) -> (i32, i32) {
    let pixel_index = row as u64 * context.image_width as u64 + column as u64;
    let (x, y) = (column as Float + 0.5, row as Float + 0.5);
    let ray = (context.camera).sample_ray(x, y, &context.sampler.sample(pixel_index, 0));
    match context.scene.intersect_object(&ray) {
        Some((hit, object)) => (object as i32, hit.material.0 as i32),
        None => (-1, -1),
    }
}
