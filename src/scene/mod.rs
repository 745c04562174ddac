//! Scenes: reading files into a [`SceneDescription`], and building the renderable
//! [`Scene`] (primitives in BVH leaf order, materials, lights).

mod compose;
mod error;
mod file;
mod info;
mod lex;
mod load;
mod mtl;
mod obj;
mod ply;
mod toml_scene;

pub use compose::Transform;
pub use error::{IndexKind, ParseErrorKind, SceneError};
pub use info::{MaterialUse, MemoryEstimate, SceneSummary};
pub use load::{LoadedScene, SceneFormat, load, load_mesh};
pub use mtl::parse_mtl;
pub use obj::{load_obj, parse_obj};
pub use ply::{load_ply, parse_ply};
pub use toml_scene::{load_toml, parse_toml};

pub(crate) use file::read_file;

use rayon::prelude::*;

use crate::bvh::{Bvh, BvhParams, RayQuery};
use crate::material::{Material, MaterialId, PointLight};
use crate::math::{Aabb, Float, Ray, Vec2, Vec3, try_unit};
use crate::memory;
use crate::shapes::{PrimHit, Shape, Sphere, Triangle};

/// A scene as read from files: plain data, indices resolved to 0-based, nothing
/// built yet. Shapes, lights and materials keep file order.
#[derive(Clone, Debug, Default)]
pub struct SceneDescription {
    /// `v` positions.
    pub positions: Vec<Vec3>,
    /// `vt` texture coordinates (read and checked, not used by the renderer).
    pub texcoords: Vec<Vec2>,
    /// `vn` normals, as written (not normalized).
    pub normals: Vec<Vec3>,
    /// Triangles after splitting polygons into fans.
    pub triangles: Vec<TriangleDesc>,
    /// `S` spheres.
    pub spheres: Vec<SphereDesc>,
    /// `P` lights.
    pub lights: Vec<PointLight>,
    /// Materials of all `mtllib` files in order, then the fallback material if any
    /// shape needed it.
    pub materials: Vec<Material>,
    /// Non-fatal problems, each naming file and line, for the caller to show.
    pub warnings: Vec<String>,
}

/// A triangle of a description: indices into its arrays.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleDesc {
    /// Indices into [`SceneDescription::positions`].
    pub positions: [u32; 3],
    /// Indices into [`SceneDescription::normals`], when every corner has one.
    pub normals: Option<[u32; 3]>,
    /// The material.
    pub material: MaterialId,
}

/// A sphere of a description.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SphereDesc {
    /// Centre.
    pub center: Vec3,
    /// Radius, not negative.
    pub radius: Float,
    /// The material.
    pub material: MaterialId,
}

/// Distance, relative to the magnitude of the hit point's coordinates (at least 1),
/// by which secondary rays start off the surface.
const SPAWN_OFFSET: Float = 1e-4;

/// Shading data of one primitive, stored in leaf order beside the shapes.
#[derive(Clone, Copy, Debug)]
struct PrimShading {
    material: MaterialId,
    /// Index into `Scene::vertex_normals`, or `NO_NORMALS`.
    vertex_normals: u32,
}

const NO_NORMALS: u32 = u32::MAX;

/// Whether `try_unit(v)` is `Some` (finite and not zero), without normalizing: the
/// build asks it of every triangle.
#[inline]
fn has_direction(v: Vec3) -> bool {
    v.is_finite() && v != Vec3::ZERO
}

/// A renderable scene: shapes in BVH leaf order with their shading data, materials,
/// lights and the BVH.
#[derive(Clone, Debug)]
pub struct Scene {
    shapes: Vec<Shape>,
    shading: Vec<PrimShading>,
    /// Unit vertex normals of triangles that have them, one triple per triangle.
    vertex_normals: Vec<[Vec3; 3]>,
    /// The materials, indexed by [`MaterialId`].
    pub materials: Vec<Material>,
    /// The point lights.
    pub lights: Vec<PointLight>,
    bvh: Bvh,
    /// Warnings from reading and building.
    pub warnings: Vec<String>,
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
    /// The material.
    pub material: MaterialId,
}

impl Hit {
    /// A ray leaving the hit point along `dir`, started off the surface on the side
    /// it leaves towards so that it cannot hit the point it leaves.
    #[inline]
    pub fn spawn_ray(&self, dir: Vec3) -> Ray {
        Ray::new(self.offset_origin(dir), dir)
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

impl Scene {
    /// Builds the scene: drops degenerate triangles (with one warning that counts
    /// them), builds the BVH and stores primitives in its leaf order.
    pub fn build(description: SceneDescription, params: &BvhParams) -> Scene {
        let SceneDescription {
            positions,
            normals,
            triangles,
            spheres,
            lights,
            materials,
            mut warnings,
            ..
        } = description;

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
        let (bvh, order) = Bvh::build_filtered(
            triangle_count + spheres.len(),
            |i| match triangles.get(i) {
                Some(t) => {
                    let [a, b, c] = corners(t);
                    let triangle = Triangle::new(a, b, c);
                    // No normal: zero area, or an area beyond f32 (vertices near 1e38).
                    // The box is that of the stored form (v0 and edges), whose rounded
                    // corners the kernel intersects, not of the file's corners.
                    has_direction(triangle.normal()).then(|| triangle.bounds())
                }
                None => Some(sphere_shape(&spheres[i - triangle_count]).bounds()),
            },
            params,
        );

        let degenerate = triangle_count + spheres.len() - order.len();
        if degenerate > 0 {
            warnings.push(format!(
                "skipped {degenerate} degenerate (zero-area) triangle{}",
                if degenerate == 1 { "" } else { "s" }
            ));
        }
        if order.is_empty() {
            warnings.push("the scene has no shapes left to render: every ray misses".into());
        }
        if lights.is_empty() {
            warnings.push(
                "the scene has no lights ('P'): full mode shows only ambient and emitted colour"
                    .into(),
            );
        }

        // Step 2: shapes and shading data in leaf order, on all threads, reading each
        // triangle once. Vertex normals are numbered in leaf order afterwards.
        const HAS_NORMALS: u32 = 0;
        let mut shapes = Vec::with_capacity(order.len());
        let mut shading = Vec::with_capacity(order.len());
        memory::advise_huge_pages(&shapes);
        memory::advise_huge_pages(&shading);
        order
            .par_iter()
            .map(|&i| match triangles.get(i as usize) {
                Some(t) => {
                    let [a, b, c] = corners(t);
                    let shading = PrimShading {
                        material: t.material,
                        vertex_normals: if t.normals.is_some() {
                            HAS_NORMALS
                        } else {
                            NO_NORMALS
                        },
                    };
                    (Shape::Triangle(Triangle::new(a, b, c)), shading)
                }
                None => {
                    let sphere = &spheres[i as usize - triangle_count];
                    let shading = PrimShading {
                        material: sphere.material,
                        vertex_normals: NO_NORMALS,
                    };
                    (Shape::Sphere(sphere_shape(sphere)), shading)
                }
            })
            .unzip_into_vecs(&mut shapes, &mut shading);
        let mut normal_count = 0;
        for s in shading
            .iter_mut()
            .filter(|s| s.vertex_normals != NO_NORMALS)
        {
            s.vertex_normals = normal_count;
            normal_count += 1;
        }
        let vertex_normals = if normal_count == 0 {
            Vec::new()
        } else {
            order
                .par_iter()
                .filter_map(|&i| {
                    let t = triangles.get(i as usize)?;
                    let ids = t.normals?;
                    let [a, b, c] = corners(t);
                    let Some(unit) = try_unit(Triangle::new(a, b, c).normal()) else {
                        unreachable!("degenerate triangles were left out")
                    };
                    // A zero-length `vn` cannot be normalized: use the geometric normal.
                    Some(ids.map(|n| try_unit(normals[n as usize]).unwrap_or(unit)))
                })
                .collect()
        };
        Scene {
            shapes,
            shading,
            vertex_normals,
            materials,
            lights,
            bvh,
            warnings,
        }
    }

    /// The BVH over the scene's primitives.
    pub fn bvh(&self) -> &Bvh {
        &self.bvh
    }

    /// Number of primitives (triangles and spheres).
    pub fn prim_count(&self) -> usize {
        self.shapes.len()
    }

    /// The primitives' boxes in leaf order, for [`Bvh::validate`].
    pub fn prim_bounds(&self) -> Vec<Aabb> {
        self.shapes.iter().map(Shape::bounds).collect()
    }

    /// The closest hit along `ray`, if any.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let query = RayQuery::new(ray);
        let mut closest: Option<(u32, PrimHit)> = None;
        self.bvh.intersect(&query, Float::INFINITY, |prim, t_max| {
            let hit = self.shape(prim).intersect(ray, t_max)?;
            closest = Some((prim, hit));
            Some(hit.t)
        });
        closest.map(|(prim, hit)| self.hit_details(ray, prim, hit))
    }

    /// Whether anything blocks `ray` before distance `t_max`.
    #[inline]
    pub fn occluded(&self, ray: &Ray, t_max: Float) -> bool {
        let query = RayQuery::new(ray);
        self.bvh.occluded(&query, t_max, |prim, t_max| {
            self.shape(prim).intersect(ray, t_max).is_some()
        })
    }

    /// The closest hit by testing every primitive: the slow reference for tests.
    pub fn intersect_linear(&self, ray: &Ray) -> Option<Hit> {
        let mut closest: Option<(u32, PrimHit)> = None;
        let mut t_max = Float::INFINITY;
        for (prim, shape) in self.shapes.iter().enumerate() {
            if let Some(hit) = shape.intersect(ray, t_max) {
                t_max = hit.t;
                closest = Some((prim as u32, hit));
            }
        }
        closest.map(|(prim, hit)| self.hit_details(ray, prim, hit))
    }

    #[inline(always)]
    fn shape(&self, prim: u32) -> &Shape {
        debug_assert!((prim as usize) < self.shapes.len());
        &self.shapes[prim as usize]
    }

    /// Second phase of a hit: point, normals and material, for the closest hit only.
    fn hit_details(&self, ray: &Ray, prim: u32, hit: PrimHit) -> Hit {
        let shading = self.shading[prim as usize];
        let (p, n, ns) = match self.shape(prim) {
            Shape::Triangle(tri) => {
                // `build` kept only triangles whose normal `try_unit` accepts.
                let n = try_unit(tri.normal()).unwrap_or(-ray.dir);
                let ns = match shading.vertex_normals {
                    NO_NORMALS => n,
                    i => {
                        let [n0, n1, n2] = self.vertex_normals[i as usize];
                        let w = 1.0 - hit.u - hit.v;
                        try_unit(n0 * w + n1 * hit.u + n2 * hit.v).unwrap_or(n)
                    }
                };
                (ray.at(hit.t), n, ns)
            }
            Shape::Sphere(s) => {
                let p = ray.at(hit.t);
                let n = try_unit(p - s.center).unwrap_or(-ray.dir);
                (s.center + n * s.radius, n, n)
            }
        };
        let face = |v: Vec3| if v.dot(ray.dir) > 0.0 { -v } else { v };
        Hit {
            t: hit.t,
            p,
            n: face(n),
            ns: face(ns),
            material: shading.material,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn has_direction_agrees_with_try_unit() {
        let tiny = f32::from_bits(1);
        let values = [
            0.0,
            -0.0,
            tiny,
            -tiny,
            1e-30,
            1.0,
            -3.5,
            1e30,
            f32::MAX,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        for &x in &values {
            for &y in &values {
                for &z in &values {
                    let v = Vec3::new(x, y, z);
                    assert_eq!(has_direction(v), try_unit(v).is_some(), "{v:?}");
                }
            }
        }
    }
}
