//! Non-finite values (NaN or infinite) in vertex positions, normals and texture
//! coordinates, which scanners, converters and some exporters write and which Assimp,
//! Blender and trimesh read (they keep the values as they are): they are kept, and
//! one warning per file counts them. The triangles with a corner at a non-finite
//! position are dropped, so that no NaN reaches the BVH (a box with a NaN corner breaks
//! its slab tests); those with a non-finite normal or texture coordinate lose that
//! attribute, as a face written without `vn` or `vt` has none, so that no NaN reaches
//! shading: they are shaded with their geometric normal, and read their textures at
//! (0, 0).

use std::path::Path;

use rayon::prelude::*;

use crate::description::SceneDescription;

/// What was not finite in a file, and what the triangles lost to it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Dropped {
    /// Positions not finite.
    pub(crate) vertices: usize,
    /// Triangles dropped, for a corner at one of those positions.
    pub(crate) triangles: usize,
    /// Normals not finite.
    pub(crate) normals: usize,
    /// Triangles (kept) that lost their normals to them.
    pub(crate) unsmoothed: usize,
    /// Texture coordinates not finite.
    pub(crate) texcoords: usize,
    /// Triangles (kept) that lost their texture coordinates to them.
    pub(crate) unmapped: usize,
}

impl std::ops::AddAssign for Dropped {
    fn add_assign(&mut self, more: Dropped) {
        self.vertices += more.vertices;
        self.triangles += more.triangles;
        self.normals += more.normals;
        self.unsmoothed += more.unsmoothed;
        self.texcoords += more.texcoords;
        self.unmapped += more.unmapped;
    }
}

impl Dropped {
    /// The one warning of a file, naming it; `None` when every value was finite.
    pub(crate) fn warning(self, path: &Path) -> Option<String> {
        let parts: Vec<String> = [
            (
                self.vertices,
                "vertex",
                "vertices",
                self.triangles,
                "dropped",
            ),
            (
                self.normals,
                "normal",
                "normals",
                self.unsmoothed,
                "shaded flat",
            ),
            (
                self.texcoords,
                "texture coordinate",
                "texture coordinates",
                self.unmapped,
                "left without texture coordinates (its textures read at (0, 0))",
            ),
        ]
        .into_iter()
        // A normal or texture coordinate no kept triangle uses changes nothing (a PLY
        // vertex with a NaN normal is dropped as one at a NaN position).
        .filter(|&(bad, one, _, lost, _)| bad > 0 && (one == "vertex" || lost > 0))
        .map(|(bad, one, many, lost, what)| {
            let (values, them) = match bad {
                1 => (format!("1 {one}"), "it"),
                _ => (format!("{bad} {many}"), "them"),
            };
            let lost = match lost {
                0 => format!("no triangle uses {them}"),
                1 => format!("the 1 triangle using {them} is {what}"),
                n => format!("the {n} triangles using {them} are {what}"),
            };
            format!("{values} with a non-finite coordinate (NaN or infinite); {lost}")
        })
        .collect();
        (!parts.is_empty()).then(|| format!("{}: {}", path.display(), parts.join("; ")))
    }
}

/// Drops the triangles of `scene` and of its `meshes` that have a corner at a
/// non-finite position, keeping the arrays in step with them (normal and texture
/// coordinate indices, the objects' first triangles), takes their normals or texture
/// coordinates from the triangles with a corner at a non-finite one, and adds one
/// warning naming `path` if any value was not finite. Vertices, normals and texture
/// coordinates stay where they are, so indices into them do not change; no triangle
/// refers to a non-finite one.
pub(crate) fn drop_non_finite_triangles(scene: &mut SceneDescription, path: &Path) {
    let mut dropped = drop_in(scene);
    for mesh in &mut scene.meshes {
        dropped += drop_in(mesh);
    }
    scene.warnings.extend(dropped.warning(path));
}

/// [`drop_non_finite_triangles`] for one description, without its meshes.
fn drop_in(scene: &mut SceneDescription) -> Dropped {
    let (vertices, triangles) = drop_at_positions(scene);
    let (normals, unsmoothed) = forget(&mut scene.triangle_normals, &scene.normals, |n| {
        n.is_finite()
    });
    let (texcoords, unmapped) = forget(&mut scene.triangle_texcoords, &scene.texcoords, |t| {
        t.is_finite()
    });
    Dropped {
        vertices,
        triangles,
        normals,
        unsmoothed,
        texcoords,
        unmapped,
    }
}

/// Sets to `None` the corners' indices in `indices` of the triangles with a corner
/// at a value of `values` that is not `finite`; the number of such values, and of
/// such triangles.
fn forget<T: Sync>(
    indices: &mut [Option<[u32; 3]>],
    values: &[T],
    finite: impl Fn(&T) -> bool + Sync,
) -> (usize, usize) {
    // The common case, every value finite, costs this one pass.
    let bad = values.par_iter().filter(|v| !finite(v)).count();
    if bad == 0 {
        return (0, 0);
    }
    let lost = indices
        .par_iter_mut()
        .map(|corners| {
            let at_bad = corners.is_some_and(|c| {
                c.iter()
                    .any(|&i| values.get(i as usize).is_some_and(|v| !finite(v)))
            });
            if at_bad {
                *corners = None;
            }
            usize::from(at_bad)
        })
        .sum();
    (bad, lost)
}

/// Drops the triangles with a corner at a non-finite position; the number of such
/// positions, and of the triangles dropped.
fn drop_at_positions(scene: &mut SceneDescription) -> (usize, usize) {
    // The common case, every vertex finite, costs this one pass.
    let vertices = scene
        .positions
        .par_iter()
        .filter(|p| !p.is_finite())
        .count();
    if vertices == 0 {
        return (0, 0);
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
    (vertices, triangles)
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
