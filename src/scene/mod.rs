//! The renderable scene: a [`SceneDescription`] turned into primitives in BVH leaf
//! order with their shading data, materials and lights ([`Scene::build`]), the closest
//! and any-hit queries rays make, and a summary of a description ([`SceneSummary`]).

mod batch;
mod build;
mod info;
mod instances;
mod objects;
mod packet;
mod query;
mod shading;
mod stream;
mod tangents;
#[cfg(test)]
pub(crate) use packet::tests as packet_tests;

pub use batch::BATCH;
pub use info::{MaterialUse, MemoryEstimate, SceneSummary};

use std::mem::MaybeUninit;

use rayon::prelude::*;

use crate::bvh::{Bvh, BvhInvariantError, BvhParams, RayQuery, WideBvh};
use crate::description::{SceneDescription, SphereDesc, TriangleDesc};
use crate::lights::environment::Environment;
use crate::lights::{AreaLights, AreaLightsBuilder};
use crate::material::{BlendRule, Cutout, Light, Material, MaterialId};
use crate::math::{Aabb, Float, Ray, Vec2, Vec3, nearest_in_mask, try_unit};
use crate::memory;
use crate::shapes::{LANES, MAX_PRIM, PacketRay, PrimHit, Shape, Sphere, Triangle, TrianglePacket};
use crate::stats::{Mark, Usage};

/// Distance, relative to the magnitude of the hit point's coordinates (at least 1),
/// by which secondary rays start off the surface (also read by the packet shading,
/// `integrators::phong_lanes`).
pub(crate) const SPAWN_OFFSET: Float = 1e-4;

/// Below this cosine between a triangle's geometric normal and the way to a light, a
/// shadow ray starts from the smooth surface its vertex normals describe
/// ([`Hit::lift`]), all the way at a cosine of 0 and beyond: where the light grazes a
/// flat triangle of a smooth mesh, or lies behind it while the shading normal still
/// faces it (the shadow terminator). Above it, shadow rays start on the triangle, so
/// that a lift never carries them past a nearby occluder. Blender's default for its
/// "shadow terminator geometry offset" is the same 0.1.
pub(crate) const TERMINATOR_COSINE: Float = 0.1;

/// How much of [`Hit::lift`] a shadow ray's origin takes, from the cosine `cos`
/// between the geometric normal (facing the ray) and the unit way to the light:
/// `1 - cos / TERMINATOR_COSINE`, within 0..1.
#[inline(always)]
pub(crate) fn terminator_share(cos: Float) -> Float {
    (1.0 - cos / TERMINATOR_COSINE).clamp(0.0, 1.0)
}

/// Shading data of one primitive, in leaf order.
#[derive(Clone, Copy, Debug)]
struct PrimShading {
    material: MaterialId,
    /// Indices into `Scene::vertex_normals` of the corners' normals, or
    /// `[NO_NORMALS; 3]`.
    normals: [u32; 3],
}

const NO_NORMALS: u32 = u32::MAX;

/// The shading data of every primitive, in leaf order: its material, and the
/// indices of its corners' normals only if the scene has vertex normals (most big
/// meshes, scans among them, have none: 12 bytes a primitive saved, 10 MB on the
/// dragon).
#[derive(Clone, Debug, Default)]
struct ShadingData {
    materials: Vec<MaterialId>,
    /// Empty, or one entry per primitive (`[NO_NORMALS; 3]` for those without).
    normals: Vec<[u32; 3]>,
}

impl ShadingData {
    /// Primitive `prim`'s shading data.
    #[inline(always)]
    fn get(&self, prim: u32) -> PrimShading {
        PrimShading {
            material: self.materials[prim as usize],
            normals: self
                .normals
                .get(prim as usize)
                .copied()
                .unwrap_or([NO_NORMALS; 3]),
        }
    }

    fn len(&self) -> usize {
        self.materials.len()
    }
}

/// Marks a primitive without texture coordinates in `Scene::prim_texcoords`.
const NO_TEXCOORDS: u32 = u32::MAX;

/// Marks a primitive without vertex colours in `Scene::prim_colours`.
const NO_COLOURS: u32 = u32::MAX;

/// How long each step of [`Scene::build`] took, for `--stats`. Kept apart from
/// [`BvhSummary`], which two builds of one scene share exactly.
#[derive(Clone, Copy, Debug, Default)]
pub struct BuildTimes {
    /// The binary BVH: the primitives' boxes, then binned SAH from the root (built
    /// twice where duplicate shapes are dropped); beside it, an environment map's
    /// sampling tables and the vertex tangents MikkTSpace makes.
    pub tree: std::time::Duration,
    /// Collapsing it into the 8-wide BVH (its SAH cost measured beside it).
    pub collapse: std::time::Duration,
    /// The triangle packets and shading data in leaf order, and the rest of the
    /// scene's arrays. Most of what it writes is fresh memory, so on machines where
    /// a page's first touch is slow (virtual machines) this step varies the most.
    pub packets: std::time::Duration,
    /// The CPU time and page faults of the three steps, where the OS reports them.
    pub usage: Option<BuildUsage>,
}

/// The process's [`Usage`] over each step of [`Scene::build`] (all threads: nothing
/// else runs beside a build in the `raytracer` command).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BuildUsage {
    /// Over [`BuildTimes::tree`].
    pub tree: Usage,
    /// Over [`BuildTimes::collapse`].
    pub collapse: Usage,
    /// Over [`BuildTimes::packets`].
    pub packets: Usage,
}

/// Figures about the binary BVH the scene was built with, kept after it is collapsed
/// into the wide one that rays traverse.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BvhSummary {
    /// Nodes of the binary BVH.
    pub nodes: usize,
    /// Its greatest depth, the root being depth 0.
    pub max_depth: usize,
    /// Its SAH cost ([`Bvh::sah_cost`]).
    pub sah_cost: f64,
    /// Nodes of the wide BVH.
    pub wide_nodes: usize,
    /// The wide BVH's SAH cost ([`WideBvh::sah_cost`], a leaf priced by its
    /// packets).
    pub wide_sah_cost: f64,
    /// SIMD primitive packets in the wide BVH's leaves.
    pub packets: usize,
    /// The box around all primitives (empty for an empty scene).
    pub bounds: Aabb,
}

/// A renderable scene: primitives in BVH leaf order (their geometry in the SIMD
/// packets of the wide BVH's leaves) with their shading data, materials and lights.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The BVH that rays traverse, its leaves ranges of `packets`.
    wide: WideBvh,
    /// The primitives' geometry, grouped by four for SIMD tests: the only copy.
    packets: Vec<TrianglePacket>,
    /// Shading data by primitive (leaf order).
    shading: ShadingData,
    /// The description's vertex normals, unit length, or zero where a `vn` has no
    /// direction (the geometric normal stands in for it then).
    vertex_normals: Vec<Vec3>,
    /// The description's texture coordinates; empty unless some material has maps.
    texcoords: Vec<Vec2>,
    /// The description index of each primitive (leaf order): its triangles in
    /// order, then its spheres. Read only to answer [`Scene::source_index`], so it
    /// stays out of the caches that rays use.
    source: Vec<u32>,
    /// Which object each primitive belongs to ([`Scene::object_names`]).
    objects: objects::Objects,
    /// Indices into `texcoords` of each primitive's corners (leaf order), or
    /// `[NO_TEXCOORDS; 3]`; empty unless some material has maps, so that untextured
    /// scenes neither store nor interpolate texture coordinates.
    prim_texcoords: Vec<[u32; 3]>,
    /// Vertex tangents (unit `xyz`, `w` the bitangent's sign, ±1) of the triangles
    /// whose material reads a tangent frame: a file's or MikkTSpace's
    /// (`scene::tangents`). Empty when no material does.
    tangents: Vec<glam::Vec4>,
    /// Indices into `tangents` of each primitive's corners (leaf order), or
    /// `[NO_TANGENTS; 3]`; empty unless some triangle has vertex tangents.
    prim_tangents: Vec<[u32; 3]>,
    /// Whether hits take the second phase, [`Scene::textured_hit_details`]: the
    /// scene has texture coordinates for its maps, or vertex colours. One flag, so
    /// that a coloured scene without maps stores no texture coordinate indices.
    second_phase: bool,
    /// The description's vertex colours ([`SceneDescription::colours`]); empty
    /// unless some triangle has one.
    colours: Vec<Vec3>,
    /// Indices into `colours` of each primitive's corners (leaf order), or
    /// `[NO_COLOURS; 3]`; empty in a scene without vertex colours.
    prim_colours: Vec<[u32; 3]>,
    /// Whether some material cuts its surface out (`map_d`, glTF's alpha mask): rays
    /// then take the traversal that tests alpha on every candidate hit. Chosen once
    /// per ray by this flag, so scenes without cutouts pay one predictable branch.
    has_cutouts: bool,
    /// Whether the packet, stream and batch queries trace ray by ray through the
    /// single-ray queries: for cutouts, and for instances.
    ray_by_ray: bool,
    /// The instances and the meshes they place (`None` for a one-level scene, which
    /// then never looks at them).
    instances: Option<Box<instances::Instances>>,
    /// The materials, indexed by [`MaterialId`].
    pub materials: Vec<Material>,
    /// The point lights.
    pub lights: Vec<Light>,
    /// The triangles and spheres whose material emits (`Ke`), for path mode.
    pub area_lights: AreaLights,
    summary: BvhSummary,
    build_times: BuildTimes,
    /// Warnings from reading and building.
    pub warnings: Vec<String>,
    /// The shapes the build dropped, of every level.
    skipped: build::Skipped,
    /// Whether nothing lights the scene
    /// ([`SceneDescription::is_unlit`](crate::SceneDescription::is_unlit)) and it has
    /// no environment: path mode then lights it with its default studio.
    pub unlit: bool,
    /// Light from infinitely far away, if the description set one.
    pub environment: Option<Environment>,
    /// What camera rays that leave the scene see in path mode, if not the
    /// environment.
    pub background: Option<Vec3>,
    /// Whether full mode's default light rig lights the scene
    /// ([`SceneDescription::lit_by_rig`](crate::SceneDescription::lit_by_rig)): set
    /// through [`Scene::set_lit_by_rig`], which tells the meshes of instances too.
    lit_by_rig: bool,
    /// Whether blended surfaces (glTF's `BLEND`) are layers for the queries
    /// ([`Scene::blend_rule`]), composited by shading, rather than stochastic
    /// transparency: full mode's one ray a pixel would show them dithered. Set
    /// through [`Scene::set_blend_in_layers`], which tells the meshes of instances too.
    blend_in_layers: bool,
    /// Half the diagonal of the scene's bounds: how far the environment's light
    /// reaches across the scene, for weighing it against the emitters.
    pub radius: Float,
}

/// The closest hit of a ray, with everything shading needs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Distance along the ray.
    pub t: Float,
    /// The hit point.
    pub p: Vec3,
    /// Unit geometric normal, facing against the ray.
    pub n: Vec3,
    /// Unit shading normal (interpolated `vn`, or `n`), facing against the ray.
    pub ns: Vec3,
    /// Texture coordinates (interpolated `vt`); zero where there are none, on
    /// materials without texture maps, and in scenes without any.
    pub uv: Vec2,
    /// The unit shading normal of a clear coat (`KHR_materials_clearcoat`) where it
    /// differs from `ns` (its own normal map, or none under the base's normal map),
    /// facing as `ns` does; zero where it is `ns`.
    pub coat_ns: Vec3,
    /// The unit direction of anisotropy of an anisotropic material
    /// (`KHR_materials_anisotropy`): the tangent along the triangle's texture
    /// coordinates' `u` turned by the material's rotation and direction map, in the
    /// plane of `u` and `v` (the tangent frame normal maps use); zero on other
    /// materials and where there are no texture coordinates (spheres, meshes
    /// without them, a degenerate UV layout), where the BSDF turns a default
    /// tangent instead ([`crate::bxdfs::Frame::anisotropic`]).
    pub tangent: Vec3,
    /// The vertex colour interpolated at the hit (linear RGB), which multiplies the
    /// diffuse or base colour of a material that takes vertex colours
    /// ([`Material::at_point`]); white where there is none, on materials without
    /// maps or vertex colours, and in scenes without either.
    pub colour: Vec3,
    /// From `p` to the smooth surface the triangle's vertex normals describe, on the
    /// side `n` faces (Hanika, "Hacking the Shadow Terminator", Ray Tracing Gems II,
    /// 2021): `p` moved out along each corner's normal by as far as it lies below that
    /// corner's tangent plane, weighted by its barycentric coordinate. Shadow rays
    /// towards a light that grazes the triangle or lies behind it start there
    /// ([`Hit::spawn_ray_to`], path mode's light samples), so that a coarse mesh with
    /// smooth normals does not shadow itself in jagged triangles where its shading
    /// says it is lit: path mode's always, full mode's under the default rig only
    /// (SPEC starts every shadow ray an epsilon off the triangle). Zero on flat
    /// triangles (vertex normals equal to the face's, or none), spheres, and where
    /// the vertex normals face away from the ray.
    pub lift: Vec3,
    /// The material.
    pub material: MaterialId,
    /// Whether the ray hit the front: the side a triangle's winding faces
    /// (counter-clockwise seen from the front) or a sphere's outside. Area lights emit
    /// from the front only, and glass is entered through it.
    pub front: bool,
}

impl Hit {
    /// A ray leaving the hit point along `dir`, started off the surface on the side
    /// it leaves towards so that it cannot hit the point it leaves.
    #[inline]
    pub fn spawn_ray(&self, dir: Vec3) -> Ray {
        Ray::new(self.offset_origin(dir), dir)
    }

    /// [`Hit::spawn_ray`] for a `dir` of unit length already, which is not normalized
    /// again (path mode's sampled directions are unit by construction).
    #[inline]
    pub fn spawn_unit_ray(&self, dir: Vec3) -> Ray {
        Ray {
            origin: self.offset_origin(dir),
            dir,
        }
    }

    /// A ray from the hit point towards `target` and the distance to it, for shadow
    /// tests against a light at `target`: from the smooth surface ([`Hit::lift`]) as
    /// far as the light grazes the triangle ([`TERMINATOR_COSINE`]).
    #[inline]
    pub fn spawn_ray_to(&self, target: Vec3) -> (Ray, Float) {
        let towards = target - self.p;
        let share = try_unit(towards).map_or(0.0, |l| terminator_share(self.n.dot(l)));
        let origin = self.offset_origin(towards) + self.lift * share;
        let to_target = target - origin;
        let distance = to_target.length();
        (
            Ray {
                origin,
                dir: to_target / distance,
            },
            distance,
        )
    }

    #[inline]
    fn offset_origin(&self, dir: Vec3) -> Vec3 {
        let scale = SPAWN_OFFSET * self.p.abs().max_element().max(1.0);
        let side = if dir.dot(self.n) >= 0.0 { 1.0 } else { -1.0 };
        self.p + self.n * (side * scale)
    }
}

/// The kinds of query a blended surface is treated apart in ([`Scene::blend_rule`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum BlendQuery {
    /// The closest hit.
    Closest,
    /// Whether anything blocks a shadow ray.
    Shadow,
}

impl Scene {
    /// Whether full mode's default light rig lights the scene
    /// ([`SceneDescription::lit_by_rig`](crate::SceneDescription::lit_by_rig)).
    pub fn lit_by_rig(&self) -> bool {
        self.lit_by_rig
    }

    /// Says whether full mode's default light rig lights the scene, in the meshes of
    /// its instances too (each built as a scene of its own): full mode then lifts
    /// its shadow rays off smooth meshes ([`Hit::lift`]) and bends their shading
    /// normals towards the eye.
    pub fn set_lit_by_rig(&mut self, lit: bool) {
        self.for_each_level(|scene| scene.lit_by_rig = lit);
    }

    /// Whether blended surfaces are layers that shading composites over what lies
    /// behind them ([`BlendRule::Layer`], [`BlendRule::Shadow`]) rather than
    /// stochastic transparency ([`BlendRule::Stochastic`]).
    pub fn blend_in_layers(&self) -> bool {
        self.blend_in_layers
    }

    /// Says whether blended surfaces are layers (full mode, whose integrator
    /// composites them) or stochastic transparency (path mode, the default), in the
    /// meshes of its instances too.
    pub fn set_blend_in_layers(&mut self, layers: bool) {
        self.for_each_level(|scene| scene.blend_in_layers = layers);
    }

    /// Whether some material is blended (glTF's `alphaMode: BLEND`).
    pub fn has_blended_materials(&self) -> bool {
        let blended = |scene: &Scene| {
            (scene.materials.iter()).any(|m| m.cutout().is_some_and(|cutout| cutout.blend))
        };
        blended(self) || (self.instances.as_ref()).is_some_and(|i| i.meshes.iter().any(blended))
    }

    /// `set` applied to this scene and to each mesh of its instances (each built as
    /// a scene of its own).
    fn for_each_level(&mut self, set: impl Fn(&mut Scene)) {
        set(self);
        if let Some(instances) = &mut self.instances {
            instances.meshes.iter_mut().for_each(set);
        }
    }

    /// How a query of `kind` along `ray` treats blended surfaces.
    #[inline]
    pub(super) fn blend_rule(&self, ray: &Ray, kind: BlendQuery) -> BlendRule {
        match (self.blend_in_layers, kind) {
            (false, _) => BlendRule::Stochastic(Cutout::ray_key(ray.origin, ray.dir)),
            (true, BlendQuery::Closest) => BlendRule::Layer,
            (true, BlendQuery::Shadow) => BlendRule::Shadow,
        }
    }

    /// Figures about the scene's BVH.
    pub fn bvh_summary(&self) -> &BvhSummary {
        &self.summary
    }

    /// How long each step of the build took.
    pub fn build_times(&self) -> BuildTimes {
        self.build_times
    }

    /// Where primitive `prim` (leaf order, as [`Scene::intersect_primitive`] names
    /// it) came from: its index among the description's triangles, in the order
    /// the file lists them, followed by its spheres (so a sphere's index is the
    /// triangle count plus its own). Degenerate triangles and copies dropped by
    /// [`Scene::build`] keep their places in this numbering: no primitive maps to them.
    ///
    /// # Panics
    /// If `prim` is not below [`Scene::prim_count`].
    ///
    /// In a scene with instances, primitives past the description's own are those
    /// of its meshes, each numbered once (not per copy), mesh by mesh, and so are
    /// their source indices.
    pub fn source_index(&self, prim: u32) -> usize {
        match (&self.instances, self.source.get(prim as usize)) {
            (_, Some(&source)) => source as usize,
            (Some(instances), None) => self.source_index_instanced(instances, prim),
            (None, None) => panic!("primitive {prim} out of range"),
        }
    }

    /// Number of primitives (triangles and spheres) stored: each mesh that instances
    /// place counts once, whatever its copies.
    pub fn prim_count(&self) -> usize {
        self.unique_prim_count()
    }

    /// Checks that the wide BVH and its packets hold every primitive exactly once,
    /// each inside the box of the leaf that holds it, and every invariant of
    /// [`WideBvh::validate`].
    ///
    /// # Errors
    /// The first broken invariant found.
    pub fn validate(&self) -> Result<(), BvhInvariantError> {
        let packet_bounds = |index: u32| {
            let packet = &self.packets[index as usize];
            (0..LANES)
                .filter_map(|lane| packet.shape(lane))
                .fold(Aabb::default(), |b, shape| b.union(shape.bounds()))
        };
        self.wide.validate(self.packets.len(), packet_bounds)?;
        let mut seen = vec![false; self.shading.len()];
        for (index, packet) in self.packets.iter().enumerate() {
            for lane in 0..LANES {
                let Some(prim) = packet.prim(lane) else {
                    continue;
                };
                match seen.get_mut(prim as usize) {
                    Some(seen) if !*seen => *seen = true,
                    _ => {
                        return Err(BvhInvariantError(format!(
                            "packet {index} holds primitive {prim} twice or out of range"
                        )));
                    }
                }
            }
        }
        match seen.iter().position(|&s| !s) {
            Some(missing) => Err(BvhInvariantError(format!(
                "primitive {missing} in no packet"
            ))),
            None => self.validate_instances(),
        }
    }
}
