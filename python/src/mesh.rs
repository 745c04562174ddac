//! A triangle mesh given as arrays (`Scene.from_mesh`): vertices and faces checked,
//! row by row, into a scene description.

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
