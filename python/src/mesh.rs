//! A triangle mesh given as arrays (`Scene.from_mesh`): vertices and faces checked,
//! row by row, into a scene description.

use std::path::PathBuf;

use numpy::PyReadonlyArrayDyn;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use raytracer::SceneDescription;
use raytracer::material::{Material, MaterialId};
use raytracer::math::Vec3;

use crate::rays::{numbers_of, rows_of, shape_text};

/// The description of the mesh of `vertices` (`(n, 3)` numbers) and `faces` (`(m, 3)`
/// integers, rows of `vertices`), every face with the fallback material.
pub(crate) fn description(
    vertices: &Bound<'_, PyAny>,
    faces: &Bound<'_, PyAny>,
) -> PyResult<SceneDescription> {
    let vertices = numbers_of(vertices, "vertices", "an (n, 3) array of numbers")?;
    let vertices = rows_of(vertices.as_array(), "vertices")?;
    let positions: Vec<Vec3> = vertices
        .rows()
        .into_iter()
        .enumerate()
        .map(|(row, v)| {
            let p = Vec3::new(v[0], v[1], v[2]);
            if p.is_finite() {
                Ok(p)
            } else {
                Err(PyValueError::new_err(format!(
                    "vertex {row}: {p} is not finite"
                )))
            }
        })
        .collect::<PyResult<_>>()?;
    let faces = indices_of(faces)?;
    let faces = faces.as_array();
    if faces.ndim() != 2 || faces.shape()[1] != 3 {
        return Err(PyValueError::new_err(format!(
            "faces must have the shape (m, 3), three vertex indices per triangle, not {}",
            shape_text(faces.shape())
        )));
    }
    let count = positions.len();
    let triangles = faces
        .rows()
        .into_iter()
        .enumerate()
        .map(|(row, face)| {
            let mut positions = [0u32; 3];
            for (corner, &index) in positions.iter_mut().zip(face.iter()) {
                *corner = u32::try_from(index)
                    .ok()
                    .filter(|&i| (i as usize) < count)
                    .ok_or_else(|| {
                        PyValueError::new_err(format!(
                            "face {row}: vertex index {index} is not in 0..{count}"
                        ))
                    })?;
            }
            Ok(raytracer::description::TriangleDesc {
                positions,
                material: MaterialId(0),
            })
        })
        .collect::<PyResult<_>>()?;
    Ok(SceneDescription {
        positions,
        triangles,
        materials: vec![Material::fallback()],
        ..SceneDescription::default()
    })
}

/// `faces` as 64-bit integers: an array (or anything numpy makes one of) of integers;
/// numbers with a fraction, which numpy would truncate, are refused.
fn indices_of<'py>(faces: &Bound<'py, PyAny>) -> PyResult<PyReadonlyArrayDyn<'py, i64>> {
    let numpy = faces.py().import("numpy")?;
    let refuse = |e: String| {
        PyValueError::new_err(format!(
            "faces must be an (m, 3) array of integers (vertex indices): {e}"
        ))
    };
    let array = numpy
        .call_method1("asarray", (faces,))
        .map_err(|e| refuse(e.to_string()))?;
    let kind: String = array.getattr("dtype")?.getattr("kind")?.extract()?;
    let size: usize = array.getattr("size")?.extract()?;
    if !matches!(kind.as_str(), "i" | "u") && size > 0 {
        let dtype = array.getattr("dtype")?.str()?.to_string();
        return Err(refuse(format!("not {dtype}")));
    }
    array
        .call_method1("astype", ("int64",))?
        .extract()
        .map_err(|e: PyErr| refuse(e.to_string()))
}

/// One mesh of `Scene.from_arrays`, as `raytracer._arrays` hands it over: checked
/// there (shapes, dtypes, finite values, indices in range, transforms), and checked
/// again here only as far as memory safety needs.
pub(crate) struct ArrayMesh<'py> {
    /// `(n, 3)` `float32`, C order.
    pub vertices: PyReadonlyArrayDyn<'py, f32>,
    /// `(m, 3)` `uint32`, C order.
    pub faces: PyReadonlyArrayDyn<'py, u32>,
    /// `(n, 3)` `float32`, or none.
    pub normals: Option<PyReadonlyArrayDyn<'py, f32>>,
    /// `(n, 2)` `float32`, or none.
    pub uvs: Option<PyReadonlyArrayDyn<'py, f32>>,
    /// The name of its material among the TOML document's, or none for the default.
    pub material: Option<String>,
    /// The image file of its base colour map, or none.
    pub texture: Option<PathBuf>,
    /// Its name, for the `object_id` output's names.
    pub name: String,
    /// `(k, 4, 4)` `float64`, row-major, world from object: the mesh stored once and
    /// placed `k` times (instances); none: placed as its vertices are (a single
    /// transform already applied).
    pub transforms: Option<PyReadonlyArrayDyn<'py, f64>>,
    /// Vertex colours: `(n, 3)` linear `float32`, or none.
    pub colours: Option<PyReadonlyArrayDyn<'py, f32>>,
}

/// The scene of `meshes` and of `loaded` (a TOML document's materials, lights and
/// environment; [`formats::parse_toml`]): each mesh without transforms appended to
/// the description's own arrays (an object of its own), each with transforms stored
/// once in [`SceneDescription::meshes`] and placed by an instance per transform.
/// Returns the description and the names of its objects in object id order (the
/// meshes' names, with `copy j` for each copy of a mesh placed more than once).
///
/// # Errors
/// A `ValueError` naming the mesh for arrays of a wrong shape, indices out of range,
/// a singular transform or a texture that cannot be read.
pub(crate) fn arrays_description(
    mut description: SceneDescription,
    meshes: &[ArrayMesh<'_>],
) -> PyResult<(SceneDescription, Vec<String>)> {
    let flat = || meshes.iter().filter(|m| m.transforms.is_none());
    let flat_normals = flat().any(|m| m.normals.is_some());
    let flat_uvs = flat().any(|m| m.uvs.is_some());
    let mut fallback = None;
    let mut names = Vec::new();
    let mut placed_names = Vec::new();
    for (k, mesh) in meshes.iter().enumerate() {
        let bad = |what: String| PyValueError::new_err(format!("meshes[{k}]: {what}"));
        let material = match &mesh.material {
            Some(name) => MaterialId(
                description
                    .materials
                    .iter()
                    .position(|m| &m.name == name)
                    .ok_or_else(|| bad(format!("no material {name:?}")))? as u32,
            ),
            None => *fallback.get_or_insert_with(|| {
                description.materials.push(Material::fallback());
                MaterialId(description.materials.len() as u32 - 1)
            }),
        };
        if let Some(path) = &mesh.texture {
            let texture = raytracer::textures::load_texture(path)
                .map_err(|e| bad(format!("texture: {e}")))?;
            let map = raytracer::textures::TextureMap::new(texture);
            let target = &mut description.materials[material.0 as usize];
            let maps = target.maps.get_or_insert_with(Default::default);
            maps.diffuse = Some(map.clone());
            if target.pbr.is_some() {
                maps.pbr.base_color = Some(map);
            }
        }
        let Some(transforms) = &mesh.transforms else {
            let object =
                raytracer::description::ObjectDesc::next_in(&description, mesh.name.clone());
            description.objects.push(object);
            names.push(mesh.name.clone());
            append_mesh(&mut description, mesh, material, (flat_normals, flat_uvs)).map_err(bad)?;
            continue;
        };
        let transforms = transforms.as_slice().map_err(|e| bad(e.to_string()))?;
        if transforms.len() % 16 != 0 {
            return Err(bad("transforms must have the shape (k, 4, 4)".into()));
        }
        let mut stored = SceneDescription::default();
        let own = (mesh.normals.is_some(), mesh.uvs.is_some());
        append_mesh(&mut stored, mesh, material, own).map_err(bad)?;
        let index = description
            .add_instanced_mesh(stored, Some(material))
            .map_err(|e| bad(e.to_string()))?;
        let copies = transforms.len() / 16;
        for (j, rows) in transforms.chunks_exact(16).enumerate() {
            let rows: &[f64; 16] = rows.try_into().expect("chunks of 16");
            let placement = raytracer::formats::affine_from_rows(rows).map_err(|e| {
                PyValueError::new_err(format!("meshes[{k}]['transforms'][{j}]: {e}"))
            })?;
            // The front follows the winding as placed, as a flattened copy's does.
            description.add_instance(index, placement, false);
            placed_names.push(match copies {
                1 => mesh.name.clone(),
                _ => format!("{} copy {j}", mesh.name),
            });
        }
    }
    // The scene numbers the description's own objects first, then each instance's.
    names.append(&mut placed_names);
    Ok((description, names))
}

/// Appends the arrays of `mesh` to `to`'s (positions, normals, texture coordinates,
/// triangles in `material`), keeping `to`'s per-triangle normal and texture
/// coordinate indices when `(normals, uvs)` say some of its meshes have them.
fn append_mesh(
    to: &mut SceneDescription,
    mesh: &ArrayMesh<'_>,
    material: MaterialId,
    (any_normals, any_uvs): (bool, bool),
) -> Result<(), String> {
    let vertices = mesh.vertices.as_slice().map_err(|e| e.to_string())?;
    let faces = mesh.faces.as_slice().map_err(|e| e.to_string())?;
    if vertices.len() % 3 != 0 || faces.len() % 3 != 0 {
        return Err("vertices and faces must have three columns".into());
    }
    let count = vertices.len() / 3;
    let base = u32::try_from(to.positions.len())
        .ok()
        .filter(|b| (*b as usize) + count <= u32::MAX as usize)
        .ok_or("more than 2^32 vertices in all")?;
    if let Some(i) = faces.iter().position(|&i| i as usize >= count) {
        return Err(format!(
            "faces[{}]: vertex index {} is not in 0..{count}",
            i / 3,
            faces[i]
        ));
    }
    let rows = |values: &[f32], width: usize, name: &str| -> Result<(), String> {
        if values.len() != count * width {
            return Err(format!(
                "{name} must have one row of {width} per vertex ({count})"
            ));
        }
        Ok(())
    };
    if let Some(colours) = &mesh.colours {
        let colours = colours.as_slice().map_err(|e| e.to_string())?;
        rows(colours, 3, "colors")?;
        let colours: Vec<Vec3> = colours
            .chunks_exact(3)
            .map(|c| Vec3::new(c[0], c[1], c[2]))
            .collect();
        to.set_colours(base as usize, &colours);
    }
    to.positions.extend(
        vertices
            .chunks_exact(3)
            .map(|v| Vec3::new(v[0], v[1], v[2])),
    );
    let normal_base = to.normals.len() as u32;
    if let Some(normals) = &mesh.normals {
        let normals = normals.as_slice().map_err(|e| e.to_string())?;
        rows(normals, 3, "normals")?;
        to.normals
            .extend(normals.chunks_exact(3).map(|v| Vec3::new(v[0], v[1], v[2])));
    }
    let uv_base = to.texcoords.len() as u32;
    if let Some(uvs) = &mesh.uvs {
        let uvs = uvs.as_slice().map_err(|e| e.to_string())?;
        rows(uvs, 2, "uvs")?;
        to.texcoords.extend(
            uvs.chunks_exact(2)
                .map(|v| raytracer::math::Vec2::new(v[0], v[1])),
        );
    }
    let corners = || faces.chunks_exact(3).map(|f| [f[0], f[1], f[2]]);
    to.triangles
        .extend(corners().map(|c| raytracer::description::TriangleDesc {
            positions: c.map(|i| base + i),
            material,
        }));
    if any_normals {
        let has = mesh.normals.is_some();
        to.triangle_normals
            .extend(corners().map(|c| has.then(|| c.map(|i| normal_base + i))));
    }
    if any_uvs {
        let has = mesh.uvs.is_some();
        to.triangle_texcoords
            .extend(corners().map(|c| has.then(|| c.map(|i| uv_base + i))));
    }
    Ok(())
}
