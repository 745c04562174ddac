//! The renderable scene: a [`SceneDescription`] turned into primitives in BVH leaf
//! order with their shading data, materials and lights ([`Scene::build`]), the closest
//! and any-hit queries rays make, and a summary of a description ([`SceneSummary`]).

mod batch;
mod info;
mod objects;
mod packet;
mod stream;
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
use crate::material::{Light, Material, MaterialId};
use crate::math::{Aabb, Float, Ray, Vec2, Vec3, nearest_in_mask, try_unit};
use crate::memory;
use crate::shapes::{LANES, MAX_PRIM, PacketRay, PrimHit, Shape, Sphere, Triangle, TrianglePacket};
use crate::stats::{Mark, Usage};

/// Distance, relative to the magnitude of the hit point's coordinates (at least 1),
/// by which secondary rays start off the surface (also read by the packet shading,
/// `integrators::phong_lanes`).
pub(crate) const SPAWN_OFFSET: Float = 1e-4;

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

/// How long each step of [`Scene::build`] took, for `--stats`. Kept apart from
/// [`BvhSummary`], which two builds of one scene share exactly.
#[derive(Clone, Copy, Debug, Default)]
pub struct BuildTimes {
    /// The binary BVH: the primitives' boxes, then binned SAH from the root (built
    /// twice where duplicate shapes are dropped).
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
    /// Whether some material cuts its surface out (`map_d`, glTF's alpha mask): rays
    /// then take the traversal that tests alpha on every candidate hit. Chosen once
    /// per ray by this flag, so scenes without cutouts pay one predictable branch.
    has_cutouts: bool,
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
    /// Whether nothing lights the scene
    /// ([`SceneDescription::is_unlit`](crate::SceneDescription::is_unlit)) and it has
    /// no environment: path mode then lights it with its default studio.
    pub unlit: bool,
    /// Light from infinitely far away, if the description set one.
    pub environment: Option<Environment>,
    /// What camera rays that leave the scene see in path mode, if not the
    /// environment.
    pub background: Option<Vec3>,
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
    /// tests against a light at `target`.
    #[inline]
    pub fn spawn_ray_to(&self, target: Vec3) -> (Ray, Float) {
        let origin = self.offset_origin(target - self.p);
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

/// What makes a primitive render exactly as another: its kind, material, and the
/// bits of its corners, normals and texture coordinates (or of its centre and radius).
type PrimKey = [u32; 29];

/// The arrays of a description that [`prim_key`] reads.
struct KeyArrays<'a> {
    triangles: &'a [TriangleDesc],
    triangle_normals: &'a [Option<[u32; 3]>],
    triangle_texcoords: &'a [Option<[u32; 3]>],
    spheres: &'a [SphereDesc],
    positions: &'a [Vec3],
    normals: &'a [Vec3],
    texcoords: &'a [Vec2],
}

fn prim_key(i: usize, arrays: &KeyArrays<'_>) -> PrimKey {
    let KeyArrays {
        triangles,
        triangle_normals,
        triangle_texcoords,
        spheres,
        positions,
        normals,
        texcoords,
    } = *arrays;
    fn put(key: &mut PrimKey, at: usize, values: &[Float]) {
        for (k, v) in values.iter().enumerate() {
            key[at + k] = v.to_bits();
        }
    }
    let mut key = [0; 29];
    let Some(t) = triangles.get(i) else {
        let s = &spheres[i - triangles.len()];
        put(&mut key, 2, &[s.center.x, s.center.y, s.center.z, s.radius]);
        key[0] = 1;
        key[1] = s.material.0;
        return key;
    };
    // An index outside its array (a description not made by a reader) stands for
    // itself, as NaN bits no value has.
    let vec3 = |array: &[Vec3], index: u32| {
        array
            .get(index as usize)
            .map_or([Float::from_bits(0x7fc0_0000 | index), 0.0, 0.0], |v| {
                v.to_array()
            })
    };
    for (k, &p) in t.positions.iter().enumerate() {
        put(&mut key, 2 + 3 * k, &vec3(positions, p));
    }
    if let Some(Some(ns)) = triangle_normals.get(i) {
        for (k, &n) in ns.iter().enumerate() {
            put(&mut key, 11 + 3 * k, &vec3(normals, n));
        }
        key[20] = 1;
    }
    if let Some(Some(ts)) = triangle_texcoords.get(i) {
        for (k, &t) in ts.iter().enumerate() {
            let uv = texcoords
                .get(t as usize)
                .map_or([Float::from_bits(0x7fc0_0000 | t), 0.0], |v| v.to_array());
            put(&mut key, 21 + 2 * k, &uv);
        }
        key[27] = 1;
    }
    key[0] = 0;
    key[1] = t.material.0;
    key
}

/// The primitives (original indices) in `ranges` of the leaf order `order` whose key
/// equals that of a primitive of lower index in the same range.
fn duplicates_in(
    ranges: &[std::ops::Range<u32>],
    order: &[u32],
    key: impl Fn(u32) -> PrimKey + Sync,
) -> Vec<u32> {
    ranges
        .par_iter()
        .flat_map_iter(|range| {
            let mut keyed: Vec<(PrimKey, u32)> = order[range.start as usize..range.end as usize]
                .iter()
                .map(|&i| (key(i), i))
                .collect();
            keyed.sort_unstable();
            let copies: Vec<u32> = keyed
                .windows(2)
                .filter(|w| w[0].0 == w[1].0)
                .map(|w| w[1].1)
                .collect();
            copies
        })
        .collect()
}

impl Scene {
    /// Builds the scene: drops degenerate triangles ([`Triangle::is_degenerate`], with
    /// one warning that counts them) and copies of a primitive (which the BVH finds
    /// for free: see [`Bvh::coincident`]), builds the BVH and stores primitives in its
    /// leaf order.
    pub fn build(description: SceneDescription, params: &BvhParams) -> Scene {
        let bounds = description.bounds();
        let unlit = description.is_unlit() && description.environment.is_none();
        let SceneDescription {
            positions,
            normals,
            texcoords,
            triangles,
            triangle_normals,
            triangle_texcoords,
            spheres,
            lights,
            materials,
            environment,
            background,
            objects,
            mut warnings,
        } = description;
        let objects = objects::Objects::new(objects, triangles.len(), spheres.len());
        let started = Mark::now();

        // Step 1: the BVH over the triangles with an area, then the spheres, straight
        // from the description (no second copy of the shapes exists while the
        // builder's own arrays do). Primitive `i < triangles.len()` is triangle `i`,
        // the rest are spheres.
        let corners = |t: &TriangleDesc| t.positions.map(|i| positions[i as usize]);
        let sphere_shape = |s: &SphereDesc| Sphere {
            center: s.center,
            radius: s.radius,
        };
        let triangle_count = triangles.len();
        let bounds_of = |i: usize| match triangles.get(i) {
            Some(t) => {
                let [a, b, c] = corners(t);
                let triangle = Triangle::new(a, b, c);
                // The box is that of the stored form (v0 and edges), whose rounded
                // corners the kernel intersects, not of the file's corners.
                (!triangle.is_degenerate()).then(|| triangle.bounds())
            }
            None => Some(sphere_shape(&spheres[i - triangle_count]).bounds()),
        };
        let (mut bvh, mut order) =
            Bvh::build_filtered(triangle_count + spheres.len(), bounds_of, params);
        // Copies of one primitive pile up in the BVH's coincident ranges, where every
        // ray would test each copy (200,000 copies of a triangle took minutes to
        // render): drop all but the first of each, and build again without them.
        let mut duplicates = 0;
        if !bvh.coincident.is_empty() {
            let arrays = KeyArrays {
                triangles: &triangles,
                triangle_normals: &triangle_normals,
                triangle_texcoords: &triangle_texcoords,
                spheres: &spheres,
                positions: &positions,
                normals: &normals,
                texcoords: &texcoords,
            };
            let key = |i: u32| prim_key(i as usize, &arrays);
            let copies = duplicates_in(&bvh.coincident, &order, key);
            if !copies.is_empty() {
                duplicates = copies.len();
                let mut dropped = vec![false; triangle_count + spheres.len()];
                for i in copies {
                    dropped[i as usize] = true;
                }
                (bvh, order) = Bvh::build_filtered(
                    triangle_count + spheres.len(),
                    |i| if dropped[i] { None } else { bounds_of(i) },
                    params,
                );
                warnings.push(format!(
                    "skipped {duplicates} duplicate shape{} (the same corners, normals, texture coordinates and material as another)",
                    if duplicates == 1 { "" } else { "s" }
                ));
            }
        }

        let tree_built = Mark::now();
        let degenerate = triangle_count + spheres.len() - order.len() - duplicates;
        if degenerate > 0 {
            warnings.push(format!(
                "skipped {degenerate} degenerate (zero-area) triangle{}",
                if degenerate == 1 { "" } else { "s" }
            ));
        }
        if order.is_empty() {
            warnings.push("the scene has no shapes left to render: every ray misses".into());
        }
        let area_lights = collect_area_lights(
            (&positions, &texcoords),
            &triangles,
            &triangle_texcoords,
            &spheres,
            &materials,
        );
        // An unlit scene is warned of (and lit) by `SceneDescription::add_default_light`,
        // which knows the mode.

        // Step 2: the wide BVH, its packets and the shading data in leaf order, in one
        // pass over the description (each primitive's description is read once, at a
        // random place); then the binary BVH can go.
        let prim_of = |prim: u32| {
            let i = order[prim as usize] as usize;
            match triangles.get(i) {
                Some(t) => {
                    let [a, b, c] = corners(t);
                    let shading = PrimShading {
                        material: t.material,
                        normals: (triangle_normals.get(i).copied().flatten())
                            .unwrap_or([NO_NORMALS; 3]),
                    };
                    (Shape::Triangle(Triangle::new(a, b, c)), shading)
                }
                None => {
                    let s = &spheres[i - triangle_count];
                    let shading = PrimShading {
                        material: s.material,
                        normals: [NO_NORMALS; 3],
                    };
                    (Shape::Sphere(sphere_shape(s)), shading)
                }
            }
        };
        // Per-primitive normals only where some triangle has them.
        let with_normals = !normals.is_empty() && triangle_normals.par_iter().any(|n| n.is_some());
        // Triangle meshes (most big scenes) count their packets without a look.
        let has_spheres = !spheres.is_empty();
        let is_sphere = |prim: u32| has_spheres && order[prim as usize] as usize >= triangle_count;
        // What `prim_of` reads, asked for ahead: the description (at a random place
        // in a big array), then the corners it names.
        let fetch = |prim: u32, corners: bool| {
            let i = order[prim as usize] as usize;
            if let Some(t) = triangles.get(i) {
                if corners {
                    for &p in &t.positions {
                        if let Some(p) = positions.get(p as usize) {
                            memory::prefetch_lines(p, 1);
                        }
                    }
                } else {
                    memory::prefetch_lines(t, 1);
                    if let Some(n) = triangle_normals.get(i) {
                        memory::prefetch_lines(n, 1);
                    }
                }
            }
        };
        // The SAH cost, another pass over the binary nodes, is taken beside the
        // collapse (whose subtrees are tasks too). Then the binary BVH goes.
        let (wide, sah_cost) = rayon::join(
            || WideBvh::collapse(&bvh, 2 * LANES as u32, params),
            || bvh.sah_cost(params),
        );
        let collapsed = Mark::now();
        let mut summary = BvhSummary {
            nodes: bvh.nodes.len(),
            max_depth: bvh.max_depth,
            sah_cost,
            wide_nodes: 0,
            wide_sah_cost: 0.0,
            packets: 0,
            bounds: bvh
                .nodes
                .first()
                .map_or(Aabb::default(), |root| root.bounds()),
        };
        drop(bvh);
        let Packetized {
            wide,
            packets,
            shading,
        } = packetize(wide, order.len(), with_normals, is_sphere, prim_of, fetch);
        summary.wide_nodes = wide.nodes.len();
        summary.wide_sah_cost = wide.sah_cost(params, |packets| packets as Float);
        summary.packets = packets.len();

        // Texture coordinates only where a material can use them. An index out of
        // range (a description not made by a reader) counts as none.
        let textured = materials.iter().any(|m| m.maps.is_some())
            && triangle_texcoords.iter().any(Option::is_some);
        let prim_texcoords: Vec<[u32; 3]> = if textured {
            let in_range = |ids: [u32; 3]| ids.iter().all(|&i| (i as usize) < texcoords.len());
            order
                .par_iter()
                .map(
                    |&i| match triangle_texcoords.get(i as usize).copied().flatten() {
                        Some(ids) if in_range(ids) => ids,
                        _ => [NO_TEXCOORDS; 3],
                    },
                )
                .collect()
        } else {
            Vec::new()
        };
        let texcoords = if textured { texcoords } else { Vec::new() };
        let has_cutouts = materials.iter().any(|m| m.cutout().is_some());
        // A zero-length `vn` cannot be normalized: zero marks it, and the hit's
        // geometric normal stands in for it.
        let vertex_normals = normals
            .par_iter()
            .map(|&n| try_unit(n).unwrap_or(Vec3::ZERO))
            .collect();
        let built = Mark::now();
        let (tree, tree_usage) = started.to(&tree_built);
        let (collapse, collapse_usage) = tree_built.to(&collapsed);
        let (packets_time, packets_usage) = collapsed.to(&built);
        let build_times = BuildTimes {
            tree,
            collapse,
            packets: packets_time,
            usage: match (tree_usage, collapse_usage, packets_usage) {
                (Some(tree), Some(collapse), Some(packets)) => Some(BuildUsage {
                    tree,
                    collapse,
                    packets,
                }),
                _ => None,
            },
        };
        let environment = environment.as_ref().map(Environment::new);
        let radius = (bounds.max - bounds.min).length() * 0.5;
        Scene {
            unlit,
            environment,
            background,
            radius: if radius.is_finite() { radius } else { 0.0 },
            wide,
            packets,
            shading,
            vertex_normals,
            texcoords,
            source: order,
            objects,
            prim_texcoords,
            has_cutouts,
            materials,
            lights,
            area_lights,
            summary,
            build_times,
            warnings,
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
    pub fn source_index(&self, prim: u32) -> usize {
        self.source[prim as usize] as usize
    }

    /// Number of primitives (triangles and spheres).
    pub fn prim_count(&self) -> usize {
        self.shading.len()
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
        let mut seen = vec![false; self.prim_count()];
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
            None => Ok(()),
        }
    }

    /// The closest hit along `ray`, if any.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let (packet, lane, hit) = self.closest_lane(ray)?;
        // Texture coordinates and bumps: in textured scenes only, out of line, so
        // that the hits of other scenes pay one predictable branch for them and are
        // written in place as before.
        if !self.prim_texcoords.is_empty() {
            return Some(self.textured_hit_details(ray, packet, lane, hit));
        }
        Some(self.hit_details(ray, packet, lane, hit))
    }

    /// The first phase of [`Scene::intersect`]: the closest primitive hit (its index
    /// in leaf order) with distance and barycentric coordinates, and no shading data.
    /// This is what ray-query libraries such as Embree return, so benchmarks compare
    /// against it. Inlined into its callers' loops (the array query's among them):
    /// 1.03x-1.05x on the 11k-triangle dragon's incoherent rays.
    #[inline(always)]
    pub fn intersect_primitive(&self, ray: &Ray) -> Option<(u32, PrimHit)> {
        self.named(self.closest_lane(ray))
    }

    /// A closest hit as packet, lane and hit, with its primitive's index (leaf
    /// order) in place of packet and lane.
    #[inline(always)]
    fn named(&self, found: Option<(u32, usize, PrimHit)>) -> Option<(u32, PrimHit)> {
        let (packet, lane, hit) = found?;
        Some((self.packets[packet as usize].prim(lane)?, hit))
    }

    /// The closest hit as the packet and lane that hold its primitive.
    #[inline(always)]
    fn closest_lane(&self, ray: &Ray) -> Option<(u32, usize, PrimHit)> {
        if self.has_cutouts {
            return self.closest_lane_with_cutouts(ray);
        }
        let query = RayQuery::new(ray);
        let lanes = PacketRay::new(ray);
        let mut closest = None;
        let mut t_max = Float::INFINITY;
        self.wide.walk_ordered(
            &query,
            &mut t_max,
            &self.packets,
            #[inline(always)]
            |first, count, t_max| {
                self.nearest_in_leaf(&lanes, first, count, t_max, &mut closest);
                false
            },
        );
        closest
    }

    /// Tests the ray in `lanes` against packets `first..first + count`, in order, and
    /// records in `closest` (packet, lane and hit) any hit nearer than `t_max`, which
    /// it lowers: the leaf test of [`Scene::closest_lane`].
    #[inline(always)]
    fn nearest_in_leaf(
        &self,
        lanes: &PacketRay,
        first: u32,
        count: u32,
        t_max: &mut Float,
        closest: &mut Option<(u32, usize, PrimHit)>,
    ) {
        let end = first + count;
        let mut index = first;
        while index < end {
            let packet = &self.packets[index as usize];
            // Two triangle packets in one eight-lane test, as most leaves of a mesh
            // are: the same hit as testing them in turn.
            if index + 1 < end
                && let next = &self.packets[index as usize + 1]
                && !packet.holds_spheres()
                && !next.holds_spheres()
            {
                if let Some((lane, hit)) =
                    TrianglePacket::intersect_pair(packet, next, lanes, *t_max)
                {
                    *t_max = hit.t;
                    *closest = Some((index + (lane / LANES) as u32, lane % LANES, hit));
                }
                index += 2;
                continue;
            }
            if let Some((lane, hit)) = packet.intersect_any_kind(lanes, *t_max) {
                *t_max = hit.t;
                *closest = Some((index, lane, hit));
            }
            index += 1;
        }
    }

    /// [`Scene::nearest_in_leaf`] for a walk that visits a ray's leaves in another
    /// order than its own walk, in a leaf whose box the ray entered at `entry`: also
    /// whether the ray's answer could depend on that order, as it can when a hit lies
    /// at exactly `t_max` (its own walk may have met it first) or a nearer one before
    /// `entry` (its own walk may have passed it by).
    #[inline(always)]
    pub(super) fn nearest_in_leaf_noting_order(
        &self,
        lanes: &PacketRay,
        first: u32,
        count: u32,
        entry: Float,
        t_max: &mut Float,
        closest: &mut Option<(u32, usize, PrimHit)>,
    ) -> bool {
        let mut order_matters = false;
        // A packet's nearest hit up to the next float after `t_max`: a hit at
        // exactly `t_max` is reported too.
        let mut note = |index: u32, lane: usize, hit: PrimHit, t_max: &mut Float| {
            if hit.t < *t_max {
                order_matters |= hit.t < entry;
                *t_max = hit.t;
                *closest = Some((index, lane, hit));
            } else {
                order_matters = true;
            }
        };
        let end = first + count;
        let mut index = first;
        while index < end {
            let packet = &self.packets[index as usize];
            if index + 1 < end
                && let next = &self.packets[index as usize + 1]
                && !packet.holds_spheres()
                && !next.holds_spheres()
            {
                // Both packets in one eight-lane test, then each one's nearest as
                // testing them in turn finds it: the second's only up to the
                // first's hit.
                let (valid, t, u, v) =
                    TrianglePacket::hits_pair(packet, next, lanes, t_max.next_up());
                let hit_at = |lane: usize| PrimHit {
                    t: t[lane],
                    u: u[lane],
                    v: v[lane],
                };
                if let Some(lane) = nearest_in_mask(valid & 0xf, &t) {
                    note(index, lane, hit_at(lane), t_max);
                }
                if let Some(lane) = nearest_in_mask(valid & 0xf0, &t)
                    && t[lane] <= *t_max
                {
                    note(index + 1, lane - LANES, hit_at(lane), t_max);
                }
                index += 2;
                continue;
            }
            if let Some((lane, hit)) = packet.intersect_any_kind(lanes, t_max.next_up()) {
                note(index, lane, hit, t_max);
            }
            index += 1;
        }
        order_matters
    }

    /// [`Scene::closest_lane`] for scenes with cutouts: a triangle hit counts only
    /// where its material keeps the surface, so within a packet the nearest kept lane
    /// wins. Out of line, so that the traversal of other scenes stays as it was.
    #[inline(never)]
    fn closest_lane_with_cutouts(&self, ray: &Ray) -> Option<(u32, usize, PrimHit)> {
        let query = RayQuery::new(ray);
        let lanes = PacketRay::new(ray);
        let mut closest = None;
        let mut t_max = Float::INFINITY;
        self.wide
            .walk_ordered(&query, &mut t_max, &self.packets, |first, count, t_max| {
                for index in first..first + count {
                    let packet = &self.packets[index as usize];
                    let found = if packet.holds_spheres() {
                        packet.intersect_any_kind(&lanes, *t_max)
                    } else {
                        self.nearest_kept_lane(packet, &lanes, *t_max)
                    };
                    if let Some((lane, hit)) = found {
                        *t_max = hit.t;
                        closest = Some((index, lane, hit));
                    }
                }
                false
            });
        closest
    }

    /// The nearest lane of a triangle packet hit within `t_max` whose surface is not
    /// cut out there (the lowest lane on equal distances, as `TrianglePacket::intersect`).
    #[inline]
    fn nearest_kept_lane(
        &self,
        packet: &TrianglePacket,
        lanes: &PacketRay,
        t_max: Float,
    ) -> Option<(usize, PrimHit)> {
        let (mut mask, t, u, v) = packet.hits(lanes, t_max);
        while let Some(best) = nearest_in_mask(mask, &t) {
            let hit = PrimHit {
                t: t[best],
                u: u[best],
                v: v[best],
            };
            match packet.prim(best) {
                Some(prim) if self.keeps(prim, hit.u, hit.v) => return Some((best, hit)),
                _ => mask &= !(1 << best),
            }
        }
        None
    }

    /// Whether primitive `prim` (a triangle) is there at barycentrics `u`, `v`: not
    /// cut out by its material's alpha.
    #[inline]
    fn keeps(&self, prim: u32, u: Float, v: Float) -> bool {
        if !self.has_cutouts {
            return true;
        }
        let material = &self.materials[self.shading.get(prim).material.0 as usize];
        match material.cutout() {
            Some(cutout) => cutout.keeps(self.uv_at(prim, u, v)),
            None => true,
        }
    }

    /// The texture coordinates of triangle `prim` at barycentrics `u`, `v`; zero
    /// when it has none.
    #[inline]
    fn uv_at(&self, prim: u32, u: Float, v: Float) -> Vec2 {
        match self.prim_texcoords.get(prim as usize) {
            None | Some([NO_TEXCOORDS, ..]) => Vec2::ZERO,
            Some(ids) => {
                let [t0, t1, t2] = ids.map(|i| self.texcoords[i as usize]);
                t0 * (1.0 - u - v) + t1 * u + t2 * v
            }
        }
    }

    /// The shading normal `ns` of triangle `prim` tilted by its material's bump or
    /// normal map at `uv`, and by its clearcoat normal map, in the tangent frame its
    /// texture coordinates give (`u` along the tangent, `v` along the bitangent, made
    /// orthonormal about `ns`); `None` without such a map, texture coordinates or a
    /// frame (a degenerate UV layout).
    #[inline]
    fn perturbed_normals(
        &self,
        prim: u32,
        triangle: &Triangle,
        material: MaterialId,
        uv: Vec2,
        ns: Vec3,
    ) -> (Option<Vec3>, Option<Vec3>) {
        let Some(maps) = self
            .materials
            .get(material.0 as usize)
            .and_then(|m| m.maps.as_deref())
            .filter(|maps| maps.perturbs_normals())
        else {
            return (None, None);
        };
        let Some((tangent, bitangent)) = self.tangents(prim, triangle, ns) else {
            return (None, None);
        };
        let tilt = |local: Vec3| try_unit(tangent * local.x + bitangent * local.y + ns * local.z);
        (
            maps.tangent_normal(uv).and_then(tilt),
            maps.coat_tangent_normal(uv).and_then(tilt),
        )
    }

    /// The unit tangent and bitangent of triangle `prim` about the unit normal `ns`,
    /// along its texture coordinates' `u` and `v`; `None` without texture coordinates
    /// or with a degenerate UV layout.
    #[inline]
    fn tangents(&self, prim: u32, triangle: &Triangle, ns: Vec3) -> Option<(Vec3, Vec3)> {
        let ids = self.prim_texcoords.get(prim as usize)?;
        if ids[0] == NO_TEXCOORDS {
            return None;
        }
        let [t0, t1, t2] = ids.map(|i| self.texcoords[i as usize]);
        let (duv1, duv2) = (t1 - t0, t2 - t0);
        let det = duv1.x * duv2.y - duv1.y * duv2.x;
        if det == 0.0 || !det.is_finite() {
            return None;
        }
        let dpdu = (triangle.e1 * duv2.y - triangle.e2 * duv1.y) / det;
        let dpdv = (triangle.e2 * duv1.x - triangle.e1 * duv2.x) / det;
        let tangent = try_unit(dpdu - ns * ns.dot(dpdu))?;
        let bitangent = ns.cross(tangent);
        // Mirrored texture layouts run `v` the other way round.
        let bitangent = if bitangent.dot(dpdv) < 0.0 {
            -bitangent
        } else {
            bitangent
        };
        Some((tangent, bitangent))
    }

    /// Whether anything blocks `ray` before distance `t_max`.
    #[inline]
    pub fn occluded(&self, ray: &Ray, t_max: Float) -> bool {
        self.occluded_inlined(ray, t_max)
    }

    /// [`Scene::occluded`], inlined into loops over rays (the array query's).
    #[inline(always)]
    fn occluded_inlined(&self, ray: &Ray, t_max: Float) -> bool {
        if self.has_cutouts {
            return self.occluded_with_cutouts(ray, t_max);
        }
        let query = RayQuery::new(ray);
        let lanes = PacketRay::new(ray);
        let mut t_max = t_max;
        self.wide
            .walk_any(&query, &mut t_max, &self.packets, |first, count, t_max| {
                self.blocker_in_leaf(&lanes, first, count, *t_max)
            })
    }

    /// Whether some primitive of packets `first..first + count` blocks the ray in
    /// `lanes` before `t_max`: the leaf test of [`Scene::occluded`].
    #[inline(always)]
    fn blocker_in_leaf(&self, lanes: &PacketRay, first: u32, count: u32, t_max: Float) -> bool {
        let mut packets = &self.packets[first as usize..(first + count) as usize];
        loop {
            match packets {
                // Two triangle packets in one eight-lane test.
                [a, b, rest @ ..] if !a.holds_spheres() && !b.holds_spheres() => {
                    if TrianglePacket::hits_pair(a, b, lanes, t_max).0 != 0 {
                        return true;
                    }
                    packets = rest;
                }
                [a, rest @ ..] => {
                    if a.occludes_any_kind(lanes, t_max) {
                        return true;
                    }
                    packets = rest;
                }
                [] => return false,
            }
        }
    }

    /// [`Scene::occluded`] for scenes with cutouts: a lane blocks the ray only where
    /// its surface is kept.
    #[inline(never)]
    fn occluded_with_cutouts(&self, ray: &Ray, t_max: Float) -> bool {
        let query = RayQuery::new(ray);
        let lanes = PacketRay::new(ray);
        let mut t_max = t_max;
        self.wide
            .walk_any(&query, &mut t_max, &self.packets, |first, count, t_max| {
                self.packets[first as usize..(first + count) as usize]
                    .iter()
                    .any(|packet| {
                        if packet.holds_spheres() {
                            return packet.occludes_any_kind(&lanes, *t_max);
                        }
                        let (mut mask, _, u, v) = packet.hits(&lanes, *t_max);
                        while mask != 0 {
                            let lane = mask.trailing_zeros() as usize;
                            mask &= mask - 1;
                            if packet
                                .prim(lane)
                                .is_some_and(|prim| self.keeps(prim, u[lane], v[lane]))
                            {
                                return true;
                            }
                        }
                        false
                    })
            })
    }

    /// The closest hit by testing every primitive with the scalar kernels: the slow
    /// reference for tests.
    pub fn intersect_linear(&self, ray: &Ray) -> Option<Hit> {
        let mut closest = None;
        let mut t_max = Float::INFINITY;
        for (index, packet) in self.packets.iter().enumerate() {
            for lane in 0..LANES {
                let Some(shape) = packet.shape(lane) else {
                    continue;
                };
                if let Some(hit) = shape.intersect(ray, t_max)
                    && (matches!(shape, Shape::Sphere(_))
                        || packet
                            .prim(lane)
                            .is_some_and(|p| self.keeps(p, hit.u, hit.v)))
                {
                    t_max = hit.t;
                    closest = Some((index as u32, lane, hit));
                }
            }
        }
        closest.map(|(packet, lane, hit)| {
            if self.prim_texcoords.is_empty() {
                self.hit_details(ray, packet, lane, hit)
            } else {
                self.textured_hit_details(ray, packet, lane, hit)
            }
        })
    }

    /// Second phase of a hit: point, normals and material, for the closest hit only
    /// (texture coordinates and bumps are added, in textured scenes only, by
    /// [`Scene::textured_hit_details`]).
    fn hit_details(&self, ray: &Ray, packet: u32, lane: usize, hit: PrimHit) -> Hit {
        self.hit_details_inline(ray, packet, lane, hit)
    }

    /// [`Scene::hit_details`] inlined into the caller, which then builds the hit in
    /// place: returned from a call, the hit is stored in pieces and read back whole,
    /// which stalls the load (no store forwarding) in path mode's batches.
    #[inline(always)]
    fn hit_details_inline(&self, ray: &Ray, packet: u32, lane: usize, hit: PrimHit) -> Hit {
        let packet = &self.packets[packet as usize];
        let (Some(prim), Some(shape)) = (packet.prim(lane), packet.shape(lane)) else {
            unreachable!("hits come from used lanes")
        };
        let shading = self.shading.get(prim);
        let (p, n, ns) = match shape {
            Shape::Triangle(tri) => {
                // `build` kept only triangles whose normal `try_unit` accepts.
                let n = try_unit(tri.normal()).unwrap_or(-ray.dir);
                (ray.at(hit.t), n, self.shading_normal(shading, n, &hit))
            }
            Shape::Sphere(s) => {
                let p = ray.at(hit.t);
                let n = try_unit(p - s.center).unwrap_or(-ray.dir);
                (s.center + n * s.radius, n, n)
            }
        };
        let front = n.dot(ray.dir) <= 0.0;
        let face = |v: Vec3| if v.dot(ray.dir) > 0.0 { -v } else { v };
        Hit {
            t: hit.t,
            p,
            n: face(n),
            ns: face(ns),
            uv: Vec2::ZERO,
            coat_ns: Vec3::ZERO,
            material: shading.material,
            front,
        }
    }

    /// The shading normal of a triangle hit: its interpolated vertex normals, or its
    /// unit geometric normal `n` (not turned to face the ray).
    #[inline(always)]
    fn shading_normal(&self, shading: PrimShading, n: Vec3, hit: &PrimHit) -> Vec3 {
        match shading.normals {
            [NO_NORMALS, ..] => n,
            ids => {
                let [n0, n1, n2] = ids.map(|i| match self.vertex_normals[i as usize] {
                    Vec3::ZERO => n,
                    unit => unit,
                });
                let w = 1.0 - hit.u - hit.v;
                try_unit(n0 * w + n1 * hit.u + n2 * hit.v).unwrap_or(n)
            }
        }
    }

    /// [`Scene::hit_details`] in a textured scene: also the texture coordinates, if
    /// the primitive is a triangle whose material has maps (the only reader of
    /// `Hit::uv`), and under a bump or normal map the tilted shading normal (turned to
    /// face the ray).
    #[inline(never)]
    fn textured_hit_details(&self, ray: &Ray, packet: u32, lane: usize, hit: PrimHit) -> Hit {
        let mut details = self.hit_details(ray, packet, lane, hit);
        let packet = &self.packets[packet as usize];
        let (Some(prim), Some(Shape::Triangle(triangle))) = (packet.prim(lane), packet.shape(lane))
        else {
            return details;
        };
        let material = details.material;
        let has_maps = self
            .materials
            .get(material.0 as usize)
            .is_some_and(|m| m.maps.is_some());
        if !has_maps {
            return details;
        }
        let uv = self.uv_at(prim, hit.u, hit.v);
        details.uv = uv;
        // The shading normal before `hit_details` turned it.
        let n = try_unit(triangle.normal()).unwrap_or(-ray.dir);
        let ns = self.shading_normal(self.shading.get(prim), n, &hit);
        // Turned with the normal they perturb, so that a bump cannot turn the shading
        // normal to the other side at grazing angles.
        let turn = |v: Vec3| if ns.dot(ray.dir) > 0.0 { -v } else { v };
        let (bumped, coat) = self.perturbed_normals(prim, &triangle, material, uv, ns);
        if let Some(bumped) = bumped {
            details.ns = turn(bumped);
            // A coat without a normal map of its own lies on the unperturbed surface.
            details.coat_ns = turn(ns);
        }
        if let Some(coat) = coat {
            details.coat_ns = turn(coat);
        }
        details
    }
}

/// The emitting triangles and spheres of a description: those whose material has a
/// `Ke` with a positive mean (and an emission map that is not all black), with their
/// corners' texture coordinates where the material has an emission map. Scenes without
/// one (most) cost one pass over the materials.
fn collect_area_lights(
    description: (&[Vec3], &[Vec2]),
    triangles: &[TriangleDesc],
    triangle_texcoords: &[Option<[u32; 3]>],
    spheres: &[SphereDesc],
    materials: &[Material],
) -> AreaLights {
    let (positions, texcoords) = description;
    let mut lights = AreaLightsBuilder::new(materials);
    if !lights.any_emits() {
        return lights.build();
    }
    let mapped = |id: MaterialId| {
        materials
            .get(id.0 as usize)
            .and_then(|m| m.maps.as_ref())
            .is_some_and(|m| m.emission.is_some())
    };
    for (i, t) in triangles.iter().enumerate() {
        // As `Scene::uv_at` gives them to hits: none (zero) when out of range.
        let uv = match triangle_texcoords.get(i).copied().flatten() {
            Some(ids) if mapped(t.material) => match ids.map(|k| texcoords.get(k as usize)) {
                [Some(&a), Some(&b), Some(&c)] => [a, b, c],
                _ => [Vec2::ZERO; 3],
            },
            _ => [Vec2::ZERO; 3],
        };
        lights.triangle(t.positions.map(|i| positions[i as usize]), uv, t.material);
    }
    for s in spheres {
        lights.sphere(s.center, s.radius, s.material);
    }
    lights.build()
}

/// What [`packetize`] makes: the wide BVH, its packets, and the shading data of
/// every primitive in leaf order.
struct Packetized {
    wide: WideBvh,
    packets: Vec<TrianglePacket>,
    shading: ShadingData,
}

/// Points the leaves of `wide` (collapsed from the binary BVH, its leaves still
/// primitive ranges) at ranges of packets, and makes the packets of each leaf from its
/// primitives (`prim_of(prim)`, leaf order): triangles four by four, spheres apart.
/// The shading data `prim_of` gives is stored in the same pass, so the description
/// is gathered once. Leaves are filled in parallel, each into its own slices of the
/// packet and shading arrays; `is_sphere` counts a leaf's packets without making
/// its shapes.
fn packetize<S, F, P>(
    mut wide: WideBvh,
    prim_count: usize,
    with_normals: bool,
    is_sphere: S,
    prim_of: F,
    fetch: P,
) -> Packetized
where
    S: Fn(u32) -> bool + Sync,
    F: Fn(u32) -> (Shape, PrimShading) + Sync,
    P: Fn(u32, bool) + Sync,
{
    assert!(
        prim_count <= MAX_PRIM as usize + 1,
        "too many primitives for packet indices"
    );
    let leaves = wide.leaf_items();
    let packet_counts: Vec<u32> = leaves
        .par_iter()
        .map(|&(first, count)| {
            let spheres = (first..first + count)
                .filter(|&prim| is_sphere(prim))
                .count();
            ((count as usize - spheres).div_ceil(LANES) + spheres.div_ceil(LANES)) as u32
        })
        .collect();
    let mut first_packets = Vec::with_capacity(leaves.len() + 1);
    first_packets.push(0u32);
    for &count in &packet_counts {
        first_packets.push(first_packets.last().unwrap() + count);
    }
    let total = *first_packets.last().unwrap() as usize;

    // Each leaf writes its own ranges of the three arrays, so the writes (and the
    // page faults of the fresh arrays) are spread over all threads: its packets at
    // `first_packets[leaf]`, its shading data at its first primitive. Leaves list
    // their primitive ranges in node order, not in primitive order, so the ranges
    // are handed out as raw parts of the arrays, which only disjoint ranges make
    // sound: the leaves' primitive ranges must tile `0..prim_count` (collapse puts
    // every primitive in one leaf), which `assert_tiles` checks. (Cutting the
    // arrays into slices in primitive order took three per-leaf tables, 10 MB of
    // fresh memory on the dragon, written on one thread.)
    assert_tiles(&leaves, prim_count);
    let mut packets: Vec<TrianglePacket> = Vec::with_capacity(total);
    memory::advise_huge_pages(&packets);
    let mut materials: Vec<MaterialId> = Vec::with_capacity(prim_count);
    memory::advise_huge_pages(&materials);
    let normal_count = if with_normals { prim_count } else { 0 };
    let mut normals: Vec<[u32; 3]> = Vec::with_capacity(normal_count);
    memory::advise_huge_pages(&normals);
    let packet_parts = Parts::new(&mut packets.spare_capacity_mut()[..total]);
    let material_parts = Parts::new(&mut materials.spare_capacity_mut()[..prim_count]);
    let normal_parts = Parts::new(&mut normals.spare_capacity_mut()[..normal_count]);
    // Leaves in runs, so that each one's primitives are asked for ahead while the
    // leaves before them are written: their descriptions four leaves ahead, their
    // corners two leaves ahead (the description is in cache by then). The gather
    // waited on memory most of the time: on the dragon this step took 50-70 ms of
    // wall time under load, 25-30 ms with the hints (one and two leaves ahead
    // gave 40-50 ms, six and three 30-40 ms).
    leaves
        .par_chunks(LEAF_RUN)
        .enumerate()
        .for_each(|(run_index, run)| {
            let ask = |leaf: usize, corners: bool| {
                if let Some(&(first, count)) = run.get(leaf) {
                    for prim in first..first + count {
                        fetch(prim, corners);
                    }
                }
            };
            for leaf in 0..DESCRIPTIONS_AHEAD {
                ask(leaf, false);
            }
            for leaf in 0..CORNERS_AHEAD {
                ask(leaf, true);
            }
            for (leaf, &(first, count)) in run.iter().enumerate() {
                ask(leaf + DESCRIPTIONS_AHEAD, false);
                ask(leaf + CORNERS_AHEAD, true);
                let index = run_index * LEAF_RUN + leaf;
                let packet_range = first_packets[index] as usize..first_packets[index + 1] as usize;
                let prims = first as usize..(first + count) as usize;
                // SAFETY: the packet ranges are consecutive prefix sums, and the
                // primitive ranges tile `0..prim_count` (checked above): no two
                // leaves share an element of any of the three arrays.
                let (out, shading) = unsafe {
                    (
                        packet_parts.range(packet_range),
                        ShadingSlots {
                            materials: material_parts.range(prims.clone()),
                            normals: if with_normals {
                                normal_parts.range(prims)
                            } else {
                                &mut []
                            },
                        },
                    )
                };
                write_leaf(first, count, &prim_of, out, shading);
            }
        });
    // SAFETY: the packet ranges cover `0..total` exactly, the primitive ranges
    // `0..prim_count`, and `write_leaf` wrote every element of its ranges (it
    // asserts so).
    unsafe {
        packets.set_len(total);
        materials.set_len(prim_count);
        normals.set_len(normal_count);
    }
    wide.assign_leaf_items(&first_packets);
    Packetized {
        wide,
        packets,
        shading: ShadingData { materials, normals },
    }
}

/// Panics unless the ranges `(first, count)` tile `0..prim_count`: none empty, none
/// overlapping, no gap.
///
/// Without a sort (which took 1-2 ms of the dragon's build): with one bit per
/// primitive marking where ranges start, the ranges must be non-empty and inside
/// `0..prim_count`, start at distinct places, one of them at 0, each end where
/// another starts (or at `prim_count`), and hold `prim_count` primitives together.
/// Then the ranges chained from 0 tile `0..prim_count`, and they alone already hold
/// every primitive, so no other range is left to overlap them.
fn assert_tiles(ranges: &[(u32, u32)], prim_count: usize) {
    let tiles = || {
        let mut starts = vec![0u64; prim_count.div_ceil(64) + 1];
        let is_start = |starts: &[u64], at: usize| starts[at / 64] >> (at % 64) & 1 != 0;
        let mut total = 0usize;
        for &(first, count) in ranges {
            let (first, count) = (first as usize, count as usize);
            if count == 0 || first >= prim_count || count > prim_count - first {
                return false;
            }
            if is_start(&starts, first) {
                return false;
            }
            starts[first / 64] |= 1 << (first % 64);
            total += count;
        }
        total == prim_count
            && (prim_count == 0 || is_start(&starts, 0))
            && ranges.iter().all(|&(first, count)| {
                let end = first as usize + count as usize;
                end == prim_count || is_start(&starts, end)
            })
    };
    assert!(tiles(), "leaves do not tile the primitives");
}

/// An array's spare capacity, handed out in ranges to the threads that write them
/// (see [`packetize`]).
struct Parts<T> {
    start: *mut MaybeUninit<T>,
    len: usize,
}

// SAFETY: `Parts` only hands out ranges, each to one thread (the caller's contract
// of `Parts::range`); `T` is written from those threads.
unsafe impl<T: Send> Sync for Parts<T> {}

impl<T> Parts<T> {
    fn new(slots: &mut [MaybeUninit<T>]) -> Parts<T> {
        Parts {
            start: slots.as_mut_ptr(),
            len: slots.len(),
        }
    }

    /// The slots of `range`.
    ///
    /// # Safety
    /// No two calls may hand out overlapping ranges while both are in use.
    #[allow(clippy::mut_from_ref)]
    unsafe fn range(&self, range: std::ops::Range<usize>) -> &mut [MaybeUninit<T>] {
        assert!(
            range.start <= range.end && range.end <= self.len,
            "range out of bounds"
        );
        // SAFETY: inside the slots `new` took; not aliased, by the caller's contract.
        unsafe { std::slice::from_raw_parts_mut(self.start.add(range.start), range.len()) }
    }
}

/// One leaf's slots of the shading data: a material per primitive, and its
/// normals' indices per primitive or none (a scene without vertex normals).
struct ShadingSlots<'a> {
    materials: &'a mut [MaybeUninit<MaterialId>],
    normals: &'a mut [MaybeUninit<[u32; 3]>],
}

/// Leaves written in a row by one thread in [`packetize`].
const LEAF_RUN: usize = 256;

/// How many leaves ahead [`packetize`] asks for the primitives' descriptions.
const DESCRIPTIONS_AHEAD: usize = 4;

/// How many leaves ahead [`packetize`] asks for the triangles' corners.
const CORNERS_AHEAD: usize = 2;

/// Writes the packets of the leaf holding primitives `first..first + count` into
/// `out`, which must have room for exactly as many as it needs, and their shading
/// data into `shading` (a material per primitive, and the normals' indices per
/// primitive unless its normal slots are empty).
fn write_leaf<F>(
    first: u32,
    count: u32,
    prim_of: &F,
    out: &mut [MaybeUninit<TrianglePacket>],
    shading: ShadingSlots<'_>,
) where
    F: Fn(u32) -> (Shape, PrimShading),
{
    assert_eq!(
        shading.materials.len(),
        count as usize,
        "material slots of a leaf"
    );
    let with_normals = !shading.normals.is_empty();
    assert!(
        !with_normals || shading.normals.len() == count as usize,
        "normal slots of a leaf"
    );
    let mut written = 0;
    let mut emit = |packet: TrianglePacket| {
        out[written].write(packet);
        written += 1;
    };
    let zero = Triangle::new(Vec3::ZERO, Vec3::ZERO, Vec3::ZERO);
    let mut triangles = [(0u32, zero); LANES];
    let mut triangle_count = 0;
    let mut spheres = [(
        0u32,
        Sphere {
            center: Vec3::ZERO,
            radius: 0.0,
        },
    ); LANES];
    let mut sphere_count = 0;
    for (i, prim) in (first..first + count).enumerate() {
        let (shape, prim_shading) = prim_of(prim);
        shading.materials[i].write(prim_shading.material);
        if with_normals {
            shading.normals[i].write(prim_shading.normals);
        }
        match shape {
            Shape::Triangle(tri) => {
                triangles[triangle_count] = (prim, tri);
                triangle_count += 1;
                if triangle_count == LANES {
                    emit(TrianglePacket::new(&triangles));
                    triangle_count = 0;
                }
            }
            Shape::Sphere(sphere) => {
                spheres[sphere_count] = (prim, sphere);
                sphere_count += 1;
                if sphere_count == LANES {
                    emit(TrianglePacket::spheres(&spheres));
                    sphere_count = 0;
                }
            }
        }
    }
    if triangle_count > 0 {
        emit(TrianglePacket::new(&triangles[..triangle_count]));
    }
    if sphere_count > 0 {
        emit(TrianglePacket::spheres(&spheres[..sphere_count]));
    }
    assert_eq!(written, out.len(), "packet count of a leaf");
}

#[cfg(test)]
mod build_tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use std::collections::HashMap;

    /// A scene whose triangles have no vertex normals keeps a material per
    /// primitive and no normal indices at all; one whose triangles have them keeps
    /// them for every primitive, and each primitive reads back the same shading
    /// data either way.
    #[test]
    fn normal_indices_are_kept_only_for_scenes_with_vertex_normals() {
        let with = packet::tests::generated_description(20, true, 3);
        let mut without = with.clone();
        without.normals.clear();
        without.triangle_normals.clear();
        let (with, without) = (
            Scene::build(with, &BvhParams::default()),
            Scene::build(without, &BvhParams::default()),
        );
        assert_eq!(with.shading.normals.len(), with.prim_count());
        assert!(without.shading.normals.is_empty());
        assert_eq!(without.shading.materials.len(), without.prim_count());
        let mut with_corner_normals = 0;
        for prim in 0..with.prim_count() as u32 {
            let (a, b) = (with.shading.get(prim), without.shading.get(prim));
            assert_eq!(a.material, b.material);
            assert_eq!(b.normals, [NO_NORMALS; 3]);
            with_corner_normals += usize::from(a.normals != [NO_NORMALS; 3]);
        }
        assert!(with_corner_normals > 0);
    }

    /// The packets step hands each leaf its ranges of the arrays only if the leaves
    /// tile the primitives.
    #[test]
    fn leaves_must_tile_the_primitives() {
        assert_tiles(&[(4, 3), (0, 4), (7, 1)], 8);
        assert_tiles(&[], 0);
        let many: Vec<(u32, u32)> = (0..1000).rev().map(|i| (3 * i, 3)).collect();
        assert_tiles(&many, 3000);
        for (ranges, prim_count) in [
            (&[(0, 4), (3, 5)][..], 8),               // overlap
            (&[(0, 4), (5, 3)][..], 8),               // gap
            (&[(0, 4), (4, 0), (4, 4)][..], 8),       // empty leaf
            (&[(0, 4)][..], 8),                       // short
            (&[(0, 4), (4, 4)][..], 7),               // long
            (&[(0, u32::MAX), (u32::MAX, 2)][..], 3), // wraps
            (&[(0, 4), (0, 4)][..], 8),               // the same leaf twice
            (&[(1, 1), (2, 2), (3, 1)][..], 4),       // chained, but not from 0
            (&[(0, 1)][..], 0),                       // no primitives
        ] {
            let result = std::panic::catch_unwind(|| assert_tiles(ranges, prim_count));
            assert!(result.is_err(), "{ranges:?} over {prim_count}");
        }
    }

    /// The build's steps are timed one after another inside it: together they take
    /// no longer than the whole build timed from outside, and a build over shapes
    /// spends its time in them (not all of it in one). Their CPU time and faults,
    /// read from the process's counters, likewise add up to no more than the
    /// counters moved over the whole build (other tests' threads count in both).
    #[test]
    fn build_steps_are_timed_in_turn_within_the_build() {
        let description = packet::tests::generated_description(60, true, 7);
        let started = Mark::now();
        let scene = Scene::build(description, &BvhParams::default());
        let (whole, usage_whole) = started.to(&Mark::now());
        let steps = scene.build_times();
        assert!(
            steps.tree + steps.collapse + steps.packets <= whole,
            "{steps:?} beyond {whole:?}"
        );
        assert!(steps.tree > std::time::Duration::ZERO, "{steps:?}");
        assert!(steps.packets > std::time::Duration::ZERO, "{steps:?}");
        if cfg!(unix) {
            let usage = steps.usage.expect("Unix reports usage");
            let whole = usage_whole.expect("Unix reports usage");
            let parts = [usage.tree, usage.collapse, usage.packets];
            let cpu: std::time::Duration = parts.iter().map(|u| u.cpu).sum();
            let faults: u64 = parts.iter().map(|u| u.minor_faults).sum();
            assert!(cpu <= whole.cpu, "{usage:?} beyond {whole:?}");
            assert!(faults <= whole.minor_faults, "{usage:?} beyond {whole:?}");
            assert!(usage.tree.cpu > std::time::Duration::ZERO, "{usage:?}");
        }
    }

    /// The shading data is written leaf by leaf beside the packets, into slices cut
    /// in primitive order and handed to leaves listed in node order: every primitive
    /// must get the material and normals of the shape its packet lane holds. Each
    /// triangle and sphere here has a material (and a triangle its normals) of its
    /// own, found again through its first corner or centre.
    #[test]
    fn shading_data_belongs_to_the_primitive_of_its_lane() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(14);
        let mut d = SceneDescription::default();
        let triangles = 3000;
        let spheres = 60;
        let mut material_of_corner = HashMap::new();
        for t in 0..triangles {
            let a = Vec3::new(rng.random(), rng.random(), rng.random()) * 10.0;
            let corners = [
                a,
                a + Vec3::new(0.1, 0.0, 0.0),
                a + Vec3::new(0.0, 0.1, 0.05),
            ];
            let first = d.positions.len() as u32;
            d.positions.extend(corners);
            d.normals.extend([Vec3::Y; 3]);
            let material = MaterialId(t);
            material_of_corner.insert(a.to_array().map(f32::to_bits), (material, first));
            d.push_triangle(
                TriangleDesc {
                    positions: [first, first + 1, first + 2],
                    material,
                },
                Some([first, first + 1, first + 2]),
            );
        }
        let mut material_of_centre = HashMap::new();
        for s in 0..spheres {
            let center = Vec3::new(rng.random(), rng.random(), rng.random()) * 10.0;
            let material = MaterialId(triangles + s);
            material_of_centre.insert(center.to_array().map(f32::to_bits), material);
            d.spheres.push(SphereDesc {
                center,
                radius: 0.05,
                material,
            });
        }
        d.materials = vec![Material::fallback(); (triangles + spheres) as usize];
        let scene = Scene::build(d, &BvhParams::default());
        scene.validate().unwrap();
        let mut checked = 0;
        for packet in &scene.packets {
            for lane in 0..LANES {
                let (Some(prim), Some(shape)) = (packet.prim(lane), packet.shape(lane)) else {
                    continue;
                };
                let shading = scene.shading.get(prim);
                match shape {
                    Shape::Triangle(t) => {
                        let (material, first) =
                            material_of_corner[&t.v0.to_array().map(f32::to_bits)];
                        assert_eq!(shading.material, material);
                        assert_eq!(shading.normals, [first, first + 1, first + 2]);
                    }
                    Shape::Sphere(s) => {
                        let material = material_of_centre[&s.center.to_array().map(f32::to_bits)];
                        assert_eq!(shading.material, material);
                        assert_eq!(shading.normals, [NO_NORMALS; 3]);
                    }
                }
                checked += 1;
            }
        }
        assert_eq!(checked, triangles + spheres);
    }

    /// [`Scene::source_index`] names the description's triangle a ray hits, past
    /// the degenerate triangles the build drops, with the spheres after the
    /// triangles: here a grid of triangles side by side in the plane `z = 0`, listed
    /// in shuffled order, each hit from straight above its centroid.
    #[test]
    fn source_index_names_the_description_primitive() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(25);
        let mut cells: Vec<(u32, u32, bool)> = (0..30)
            .flat_map(|x| (0..30).flat_map(move |y| [(x, y, false), (x, y, true)]))
            .collect();
        for i in (1..cells.len()).rev() {
            cells.swap(i, rng.random_range(0..=i));
        }
        let mut d = SceneDescription::default();
        let mut centroids = Vec::new();
        for (i, &(x, y, upper)) in cells.iter().enumerate() {
            let (x, y) = (x as f32, y as f32);
            let corners = if upper {
                [
                    Vec3::new(x + 1.0, y, 0.0),
                    Vec3::new(x + 1.0, y + 1.0, 0.0),
                    Vec3::new(x, y + 1.0, 0.0),
                ]
            } else {
                [
                    Vec3::new(x, y, 0.0),
                    Vec3::new(x + 1.0, y, 0.0),
                    Vec3::new(x, y + 1.0, 0.0),
                ]
            };
            if i % 7 == 3 {
                // A zero-area triangle before this one: dropped, but it keeps its index.
                let first = d.positions.len() as u32;
                d.positions.extend([corners[0]; 3]);
                d.triangles.push(TriangleDesc {
                    positions: [first, first + 1, first + 2],
                    material: MaterialId(0),
                });
                centroids.push(None);
            }
            let first = d.positions.len() as u32;
            d.positions.extend(corners);
            d.triangles.push(TriangleDesc {
                positions: [first, first + 1, first + 2],
                material: MaterialId(0),
            });
            centroids.push(Some((corners[0] + corners[1] + corners[2]) / 3.0));
        }
        d.spheres.push(SphereDesc {
            center: Vec3::new(-5.0, -5.0, 0.0),
            radius: 1.0,
            material: MaterialId(0),
        });
        centroids.push(Some(Vec3::new(-5.0, -5.0, 0.0)));
        d.materials = vec![Material::fallback()];
        let scene = Scene::build(d, &BvhParams::default());
        assert!(scene.warnings.iter().any(|w| w.contains("degenerate")));
        let mut checked = 0;
        for (index, centroid) in centroids.iter().enumerate() {
            let Some(centroid) = centroid else { continue };
            let ray = Ray::new(*centroid + Vec3::new(0.0, 0.0, 3.0), -Vec3::Z);
            let (prim, _) = scene.intersect_primitive(&ray).expect("the ray hits");
            assert_eq!(
                scene.source_index(prim),
                index,
                "primitive hit above {centroid}"
            );
            checked += 1;
        }
        assert_eq!(checked, scene.prim_count());
    }
}
