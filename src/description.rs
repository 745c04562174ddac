//! The scene description: what the file readers ([`crate::formats`]) produce and
//! [`crate::scene::Scene::build`] consumes. Plain data, indices resolved to 0-based,
//! nothing built yet.

use crate::material::{Material, MaterialId, PointLight};
use crate::math::{Float, Vec2, Vec3};

/// A scene as read from files: plain data, indices resolved to 0-based, nothing
/// built yet. Shapes, lights and materials keep file order.
#[derive(Clone, Debug, Default)]
pub struct SceneDescription {
    /// `v` positions.
    pub positions: Vec<Vec3>,
    /// `vt` texture coordinates (glTF: `TEXCOORD_0`, with `v` turned up).
    pub texcoords: Vec<Vec2>,
    /// `vn` normals, as written (not normalized).
    pub normals: Vec<Vec3>,
    /// Triangles after splitting polygons into fans.
    pub triangles: Vec<TriangleDesc>,
    /// Indices into [`SceneDescription::texcoords`] of each triangle's corners, in
    /// step with `triangles` (`None` where a corner has none); or empty, when no
    /// triangle has texture coordinates or no material has a map to use them with.
    /// (Kept apart from [`TriangleDesc`] so that untextured meshes, the large ones,
    /// neither store nor copy them.)
    pub triangle_texcoords: Vec<Option<[u32; 3]>>,
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

impl SceneDescription {
    /// The texture coordinate indices of triangle `index`'s corners, if it has them.
    #[inline]
    pub fn texcoords_of(&self, index: usize) -> Option<[u32; 3]> {
        self.triangle_texcoords.get(index).copied().flatten()
    }
}

/// A triangle of a description: indices into its arrays (texture coordinates are in
/// [`SceneDescription::triangle_texcoords`]).
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
