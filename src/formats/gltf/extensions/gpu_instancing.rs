//! `EXT_mesh_gpu_instancing`: a node's `TRANSLATION`, `ROTATION` and `SCALE`
//! accessors place its mesh once per element, each placement the node's transform
//! times the element's (translation, then rotation, then scale, as a node's own).
//! The reader places the mesh through instances (read once, whatever the count),
//! not as copies.

use glam::Mat4;
use gltf::accessor::{DataType, Dimensions, Item};
use gltf::json::Value;

use super::super::{AccessorProblem, Expected, check_accessor};

/// The extension's name, as in `extensionsUsed`.
pub(in super::super) const NAME: &str = "EXT_mesh_gpu_instancing";

const TRANSLATION: Expected = Expected {
    what: "TRANSLATION",
    types: &[DataType::F32],
    dimensions: Dimensions::Vec3,
};
const ROTATION: Expected = Expected {
    what: "ROTATION",
    types: &[DataType::F32, DataType::I8, DataType::I16],
    dimensions: Dimensions::Vec4,
};
const SCALE: Expected = Expected {
    what: "SCALE",
    types: &[DataType::F32],
    dimensions: Dimensions::Vec3,
};

/// The placements (in the node's space) that `extension`, a node's
/// `EXT_mesh_gpu_instancing` object, gives: one per element of its accessors, each
/// from the same code that makes a node's matrix of its TRS properties, so that an
/// instance is exactly the node that would place it.
///
/// # Errors
/// An attribute that names no accessor, of another type, outside its buffer, with
/// another count than the others, or a value that is not finite (naming the
/// attribute and the instance); the caller names the file and the node.
pub(in super::super) fn placements<'a>(
    document: &'a gltf::Document,
    buffers: &'a [Vec<u8>],
    extension: &Value,
) -> Result<Vec<Mat4>, String> {
    let attributes = extension
        .get("attributes")
        .and_then(Value::as_object)
        .ok_or("no 'attributes' object")?;
    let accessor = |expected: &Expected| -> Result<Option<gltf::Accessor<'a>>, String> {
        let Some(index) = attributes.get(expected.what) else {
            return Ok(None);
        };
        let found = (index.as_u64())
            .and_then(|i| document.accessors().nth(usize::try_from(i).ok()?))
            .ok_or_else(|| format!("{}: accessor {index} does not exist", expected.what))?;
        match check_accessor(&found, expected, buffers) {
            Ok(()) => Ok(Some(found)),
            Err(AccessorProblem::Type(message) | AccessorProblem::Bounds(message)) => Err(message),
        }
    };
    let (translation, rotation, scale) = (
        accessor(&TRANSLATION)?,
        accessor(&ROTATION)?,
        accessor(&SCALE)?,
    );
    let counts = [&translation, &rotation, &scale].map(|a| a.as_ref().map(|a| a.count()));
    let Some(count) = counts.iter().flatten().copied().next() else {
        return Err("none of TRANSLATION, ROTATION and SCALE".into());
    };
    if counts.iter().flatten().any(|&c| c != count) {
        let [t, r, s] = counts.map(|c| c.map_or("none".to_string(), |c| c.to_string()));
        return Err(format!(
            "TRANSLATION has {t} elements, ROTATION {r}, SCALE {s}: each must have one per instance"
        ));
    }
    let data = move |buffer: gltf::Buffer<'a>| buffers.get(buffer.index()).map(Vec::as_slice);
    let read3 =
        |a: &Option<gltf::Accessor<'a>>, default: [f32; 3]| -> Result<Vec<[f32; 3]>, String> {
            match a {
                None => Ok(vec![default; count]),
                Some(a) => Ok(gltf::accessor::Iter::<[f32; 3]>::new(a.clone(), data)
                    .ok_or("data outside its buffer")?
                    .collect()),
            }
        };
    let translations = read3(&translation, [0.0; 3])?;
    let scales = read3(&scale, [1.0; 3])?;
    // Rotations may be normalized integers (`KHR_mesh_quantization`).
    fn normalized<'a, 's, T: Item + Copy + Into<f32>>(
        accessor: &gltf::Accessor<'a>,
        data: impl Clone + Fn(gltf::Buffer<'a>) -> Option<&'s [u8]>,
        max: f32,
    ) -> Option<Vec<[f32; 4]>> {
        let iter = gltf::accessor::Iter::<[T; 4]>::new(accessor.clone(), data)?;
        Some(
            iter.map(|q| q.map(|c| (c.into() / max).max(-1.0)))
                .collect(),
        )
    }
    let rotations = match &rotation {
        None => vec![[0.0, 0.0, 0.0, 1.0]; count],
        Some(a) => match a.data_type() {
            DataType::I8 => normalized::<i8>(a, data, 127.0),
            DataType::I16 => normalized::<i16>(a, data, 32767.0),
            _ => normalized::<f32>(a, data, 1.0),
        }
        .ok_or("ROTATION: data outside its buffer")?,
    };
    let mut placements = Vec::with_capacity(count);
    for (i, ((translation, rotation), scale)) in translations
        .into_iter()
        .zip(rotations)
        .zip(scales)
        .enumerate()
    {
        let finite = |values: &[f32]| values.iter().all(|v| v.is_finite());
        for (what, ok) in [
            ("TRANSLATION", finite(&translation)),
            ("ROTATION", finite(&rotation)),
            ("SCALE", finite(&scale)),
        ] {
            if !ok {
                return Err(format!("instance {i}: a {what} that is not finite"));
            }
        }
        let matrix = gltf::scene::Transform::Decomposed {
            translation,
            rotation,
            scale,
        }
        .matrix();
        placements.push(Mat4::from_cols_array_2d(&matrix));
    }
    Ok(placements)
}
