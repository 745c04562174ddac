//! Vertices at non-finite positions (NaN or infinite coordinates), which scanners,
//! converters and some exporters write and which Assimp, Blender and trimesh read:
//! they are kept, and the triangles using them dropped, with one warning per file,
//! so that no NaN reaches the BVH (a box with a NaN corner breaks its slab tests).

use std::path::Path;

use rayon::prelude::*;

use crate::description::SceneDescription;

/// How many vertices were not finite and how many triangles they took with them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Dropped {
    pub(crate) vertices: usize,
    pub(crate) triangles: usize,
}

impl Dropped {
    /// The one warning of a file, naming it; `None` when nothing was dropped.
    pub(crate) fn warning(self, path: &Path) -> Option<String> {
        if self.vertices == 0 {
            return None;
        }
        let (vertices, them) = match self.vertices {
            1 => ("vertex", "it"),
            _ => ("vertices", "them"),
        };
        let dropped = match self.triangles {
            0 => format!("no triangle uses {them}"),
            1 => format!("the 1 triangle using {them} is dropped"),
            n => format!("the {n} triangles using {them} are dropped"),
        };
        Some(format!(
            "{}: {} {vertices} with a non-finite coordinate (NaN or infinite); {dropped}",
            path.display(),
            self.vertices,
        ))
    }
}

/// Drops the triangles of `scene` and of its `meshes` that have a corner at a
/// non-finite position, keeping the arrays in step with them (normal and texture
/// coordinate indices, the objects' first triangles), and adds one warning naming
/// `path` if any vertex was not finite. Vertices stay where they are, so indices
/// into them do not change; no triangle refers to a dropped one.
pub(crate) fn drop_non_finite_triangles(scene: &mut SceneDescription, path: &Path) {
    let mut dropped = drop_in(scene);
    for mesh in &mut scene.meshes {
        let more = drop_in(mesh);
        dropped.vertices += more.vertices;
        dropped.triangles += more.triangles;
    }
    scene.warnings.extend(dropped.warning(path));
}

/// [`drop_non_finite_triangles`] for one description, without its meshes.
fn drop_in(scene: &mut SceneDescription) -> Dropped {
    // The common case, every vertex finite, costs this one pass.
    let vertices = scene
        .positions
        .par_iter()
        .filter(|p| !p.is_finite())
        .count();
    if vertices == 0 {
        return Dropped::default();
    }
    let positions = &scene.positions;
    let keep: Vec<bool> = scene
        .triangles
        .par_iter()
        .map(|t| {
            t.positions
                .iter()
                .all(|&i| positions[i as usize].is_finite())
        })
        .collect();
    let triangles = keep.iter().filter(|&&k| !k).count();
    if triangles > 0 {
        let mut objects = scene.objects.iter_mut().peekable();
        let mut kept = 0u32;
        for (index, &k) in keep.iter().enumerate() {
            while let Some(object) = objects.next_if(|o| o.first_triangle as usize <= index) {
                object.first_triangle = kept;
            }
            kept += u32::from(k);
        }
        for object in objects {
            object.first_triangle = kept;
        }
        retain_with(&mut scene.triangles, &keep);
        retain_with(&mut scene.triangle_normals, &keep);
        retain_with(&mut scene.triangle_texcoords, &keep);
    }
    Dropped {
        vertices,
        triangles,
    }
}

/// Keeps the items of `items` whose flag in `keep` is set; an empty array (one
/// that a description leaves empty when no triangle needs it) stays empty.
fn retain_with<T>(items: &mut Vec<T>, keep: &[bool]) {
    if items.is_empty() {
        return;
    }
    let mut flags = keep.iter();
    items.retain(|_| flags.next().copied().unwrap_or(true));
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::description::{ObjectDesc, TriangleDesc};
    use crate::material::MaterialId;
    use crate::math::Vec3;

    fn triangle(positions: [u32; 3]) -> TriangleDesc {
        TriangleDesc {
            positions,
            material: MaterialId(0),
        }
    }

    #[test]
    fn triangles_at_non_finite_vertices_go_with_their_indices_and_objects() {
        let mut scene = SceneDescription {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::new(f32::NAN, 0.0, 0.0), Vec3::Y],
            triangles: vec![
                triangle([0, 1, 3]),
                triangle([0, 2, 3]),
                triangle([1, 2, 3]),
            ],
            triangle_normals: vec![Some([0, 0, 0]), Some([1, 1, 1]), Some([2, 2, 2])],
            objects: ["a", "b", "c"]
                .iter()
                .zip([0, 1, 2])
                .map(|(name, first)| ObjectDesc {
                    name: name.to_string(),
                    first_triangle: first,
                    first_sphere: 0,
                })
                .collect(),
            ..SceneDescription::default()
        };
        drop_non_finite_triangles(&mut scene, Path::new("m.obj"));
        assert_eq!(scene.triangles, vec![triangle([0, 1, 3])]);
        assert_eq!(scene.triangle_normals, vec![Some([0, 0, 0])]);
        assert!(scene.triangle_texcoords.is_empty());
        let firsts: Vec<u32> = scene.objects.iter().map(|o| o.first_triangle).collect();
        assert_eq!(firsts, [0, 1, 1]);
        assert_eq!(
            scene.warnings,
            [
                "m.obj: 1 vertex with a non-finite coordinate (NaN or infinite); the 2 \
              triangles using it are dropped"
            ]
        );
    }

    #[test]
    fn finite_scenes_are_left_alone() {
        let mut scene = SceneDescription {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            triangles: vec![triangle([0, 1, 2])],
            ..SceneDescription::default()
        };
        drop_non_finite_triangles(&mut scene, Path::new("m.obj"));
        assert_eq!(scene.triangles.len(), 1);
        assert!(scene.warnings.is_empty());
    }
}
