//! `KHR_draco_mesh_compression`: a primitive's indices and attributes are one Draco
//! bitstream in a buffer view, decoded (by the pure-Rust `draco-core` crate) into the
//! arrays the reader otherwise fills from the primitive's accessors. The accessors
//! keep their counts, which the decoded mesh must match; quantised attributes come
//! back dequantised. The decoder runs under [`crate::foreign::catch_quietly`], so
//! that corrupt data is an error, never a panic.

use std::collections::HashMap;

use draco_core::draco_types::DataType;
use draco_core::geometry_attribute::PointAttribute;
use draco_core::geometry_indices::{FaceIndex, PointIndex};
use draco_core::{DecoderBuffer, Mesh, MeshDecoder};
use gltf::json::{Index, Root, Value};

/// The extension's name, as in `extensionsUsed`.
pub(in super::super) const NAME: &str = "KHR_draco_mesh_compression";

/// Gives each accessor of a compressed primitive (`draco`: their extension objects,
/// by mesh and primitive index) that has no buffer view the primitive's compressed
/// view, so that the `gltf` crate, which does not know the extension, takes them for
/// valid. The reader never reads these accessors but their counts.
pub(in super::super) fn give_views(root: &mut Root, draco: &HashMap<(usize, usize), Value>) {
    // An accessor that a primitive without the extension also reads keeps its
    // missing view (and the `gltf` crate's error).
    let mut plain = std::collections::HashSet::new();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            if !draco.contains_key(&(m, p)) {
                let accessors = primitive.attributes.values().chain(&primitive.indices);
                plain.extend(accessors.map(|a| a.value()));
            }
        }
    }
    for (&(m, p), extension) in draco {
        let Some(view) = (extension.get("bufferView").and_then(Value::as_u64))
            .and_then(|v| usize::try_from(v).ok())
            .filter(|&v| v < root.buffer_views.len())
        else {
            continue;
        };
        let Some(primitive) = root.meshes.get(m).and_then(|mesh| mesh.primitives.get(p)) else {
            continue;
        };
        let accessors: Vec<usize> = (primitive.attributes.values())
            .chain(primitive.indices.iter())
            .map(|a| a.value())
            .collect();
        for a in accessors {
            if let Some(accessor) = root.accessors.get_mut(a)
                && !plain.contains(&a)
                && accessor.buffer_view.is_none()
                && accessor.sparse.is_none()
            {
                accessor.buffer_view = Some(Index::new(view as u32));
            }
        }
    }
}

/// A decoded primitive: one entry per vertex in each attribute (`None` when the
/// extension does not name it), and three indices per triangle.
pub(in super::super) struct Decoded {
    pub(in super::super) positions: Vec<[f32; 3]>,
    pub(in super::super) normals: Option<Vec<[f32; 3]>>,
    pub(in super::super) texcoords: Option<Vec<[f32; 2]>>,
    pub(in super::super) colours: Option<Vec<[f32; 3]>>,
    pub(in super::super) indices: Vec<u32>,
}

/// What the glTF declares for the primitive: its `POSITION` accessor's count and its
/// indices accessor's count, if it has one.
pub(in super::super) struct Declared {
    pub(in super::super) vertices: usize,
    pub(in super::super) indices: Option<usize>,
    /// The texture coordinate set to read (`TEXCOORD_n`): the one its material's
    /// textures use.
    pub(in super::super) texcoord: String,
}

/// Decodes `extension`, a primitive's `KHR_draco_mesh_compression` object, whose
/// bitstream is `view` (the bytes of its buffer view, checked against the buffer by
/// the caller).
///
/// # Errors
/// An extension object without `attributes` or `POSITION`, a bitstream the decoder
/// refuses or panics on, an attribute id the stream does not hold, or counts other
/// than `declared`; the caller names the file, mesh and primitive.
pub(in super::super) fn decode(
    extension: &Value,
    view: &[u8],
    declared: &Declared,
) -> Result<Decoded, String> {
    let attributes = extension
        .get("attributes")
        .and_then(Value::as_object)
        .ok_or_else(|| format!("{NAME}: no 'attributes' object"))?;
    let id = |name: &str| -> Result<Option<u32>, String> {
        match attributes.get(name) {
            None => Ok(None),
            Some(v) => v
                .as_u64()
                .and_then(|v| u32::try_from(v).ok())
                .map(Some)
                .ok_or_else(|| format!("{NAME}: attribute {name} has id {v}, not a number")),
        }
    };
    let position_id = id("POSITION")?.ok_or_else(|| format!("{NAME}: no POSITION attribute"))?;
    let mesh = crate::foreign::catch_quietly(|| {
        let mut buffer = DecoderBuffer::new(view);
        let mut mesh = Mesh::new();
        MeshDecoder::new()
            .decode(&mut buffer, &mut mesh)
            .map(|()| mesh)
    })
    .ok_or_else(|| format!("{NAME}: the Draco data is corrupt (the decoder failed)"))?
    .map_err(|e| format!("{NAME}: the Draco data is corrupt ({e})"))?;

    let points = mesh.num_points();
    if points != declared.vertices {
        return Err(format!(
            "{NAME}: the Draco data holds {points} vertices, the POSITION accessor says {}",
            declared.vertices
        ));
    }
    let faces = mesh.num_faces();
    if let Some(count) = declared.indices
        && faces.checked_mul(3) != Some(count)
    {
        return Err(format!(
            "{NAME}: the Draco data holds {faces} triangles, the indices accessor says {count} indices"
        ));
    }
    let mut indices = Vec::with_capacity(faces * 3);
    for f in 0..faces {
        for PointIndex(i) in mesh.face(FaceIndex(f as u32)) {
            if i as usize >= points {
                return Err(format!(
                    "{NAME}: triangle {f} has vertex {i}, past the {points} vertices"
                ));
            }
            indices.push(i);
        }
    }
    let read = |name: &str, id: Option<u32>, components: usize| -> Result<_, String> {
        let Some(id) = id else { return Ok(None) };
        let attribute = mesh.attribute_by_unique_id(id).ok_or_else(|| {
            format!("{NAME}: attribute {name} has id {id}, which the Draco data does not hold")
        })?;
        values(attribute, points, components)
            .map(Some)
            .map_err(|e| format!("{NAME}: attribute {name}: {e}"))
    };
    let three = |v: Vec<f32>| v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    let positions: Vec<[f32; 3]> =
        three(read("POSITION", Some(position_id), 3)?.unwrap_or_default());
    let normals = read("NORMAL", id("NORMAL")?, 3)?.map(three);
    let texcoord = declared.texcoord.as_str();
    let texcoords = read(texcoord, id(texcoord)?, 2)?
        .map(|v| v.chunks_exact(2).map(|c| [c[0], c[1]]).collect());
    let colours = read("COLOR_0", id("COLOR_0")?, 3)?.map(three);
    Ok(Decoded {
        positions,
        normals,
        texcoords,
        colours,
        indices,
    })
}

/// The first `components` values of `attribute` at each of `points` vertices, as
/// floats (normalised integers as glTF reads them: divided by their maximum).
fn values(
    attribute: &PointAttribute,
    points: usize,
    components: usize,
) -> Result<Vec<f32>, String> {
    let has = attribute.num_components() as usize;
    if has < components {
        return Err(format!("{has} components, expected {components}"));
    }
    let data_type = attribute.data_type();
    let size = data_type.byte_length();
    let stride = usize::try_from(attribute.byte_stride()).unwrap_or(0);
    if size == 0 || stride < has * size {
        return Err(format!("values of type {data_type:?}"));
    }
    let normalized = attribute.normalized();
    let data = attribute.buffer().data();
    let mut out = Vec::with_capacity(points * components);
    for p in 0..points {
        let index = attribute.mapped_index(PointIndex(p as u32)).0 as usize;
        if index >= attribute.size() {
            return Err(format!("vertex {p} has no value"));
        }
        for c in 0..components {
            let at = index * stride + c * size;
            let bytes = data
                .get(at..at + size)
                .ok_or_else(|| format!("vertex {p}'s value lies outside the decoded data"))?;
            out.push(number(data_type, bytes, normalized));
        }
    }
    Ok(out)
}

/// One little-endian value of `data_type` as a float.
fn number(data_type: DataType, b: &[u8], normalized: bool) -> f32 {
    let scale = |value: f32, max: f32| match normalized {
        true => (value / max).max(-1.0),
        false => value,
    };
    match data_type {
        DataType::Int8 => scale(b[0] as i8 as f32, 127.0),
        DataType::Uint8 | DataType::Bool => scale(b[0] as f32, 255.0),
        DataType::Int16 => scale(i16::from_le_bytes([b[0], b[1]]) as f32, 32767.0),
        DataType::Uint16 => scale(u16::from_le_bytes([b[0], b[1]]) as f32, 65535.0),
        DataType::Int32 => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32,
        DataType::Uint32 => u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f32,
        DataType::Float32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
        DataType::Float64 => f64::from_le_bytes(b[..8].try_into().unwrap_or([0; 8])) as f32,
        DataType::Int64 => i64::from_le_bytes(b[..8].try_into().unwrap_or([0; 8])) as f32,
        DataType::Uint64 => u64::from_le_bytes(b[..8].try_into().unwrap_or([0; 8])) as f32,
        _ => f32::NAN,
    }
}
