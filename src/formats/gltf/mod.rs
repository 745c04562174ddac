//! The glTF 2.0 reader (`.gltf` with `.bin` files or data URIs, and `.glb`), through
//! the `gltf` crate: the meshes of the default scene under their node transforms,
//! materials as physically based ones ([`material`], with one file per extension in
//! [`extensions`]; see `docs/scene-format.md`), the scene's first camera as render
//! settings, and `KHR_lights_punctual` point, spot and directional lights.
//!
//! Buffers and images are read here rather than by the crate's importer, so that
//! every problem (a missing `.bin`, a truncated `.glb`, a view outside its buffer, an
//! image that does not decode) becomes an error or a warning naming the file instead
//! of a panic, and so that images go through [`load_texture`]: each file is decoded
//! once and shared.

mod context;
mod extensions;
mod material;
mod pose;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{Mat3, Mat4, Vec4};
use gltf::Document;
use gltf::json::Value;

use super::error::SceneError;
use super::file::read_regular_file;
use super::material_check::MaterialProblems;
use super::{FileAccess, LoadedScene, SceneDescription, TriangleDesc, finite, read_file};
use crate::material::{Light, LightKind, Material, MaterialId};
use crate::math::{Float, Vec2, Vec3};
use crate::options::{Origin, PartialOptions, Projection, RenderOptions, Sourced};
use crate::textures::Texture;

/// Reads a glTF file (`.gltf` or `.glb`) and the buffers and images it names,
/// relative to its folder.
///
/// # Errors
/// The file cannot be read, is not valid glTF, names a buffer that cannot be read or
/// is too short, or has a mesh whose indices point outside its vertices: each names
/// the file. A texture that cannot be read is a warning.
pub fn load_gltf(path: &Path) -> Result<LoadedScene, SceneError> {
    load_gltf_with(path, &FileAccess::anywhere())
}

/// [`load_gltf`], opening the file, its buffers and its images through `access`.
///
/// # Errors
/// As [`load_gltf`]; a buffer `access` refuses is an error, an image a warning.
pub fn load_gltf_with(path: &Path, access: &FileAccess) -> Result<LoadedScene, SceneError> {
    super::admit(path, access)?;
    let bytes = read_file(path)?;
    parse_gltf_with(&bytes, path, access)
}

/// Parses glTF or GLB bytes; `path` names the file in messages and locates the
/// files it refers to.
///
/// # Errors
/// As [`load_gltf`].
pub fn parse_gltf(bytes: &[u8], path: &Path) -> Result<LoadedScene, SceneError> {
    parse_gltf_with(bytes, path, &FileAccess::anywhere())
}

/// [`parse_gltf`], opening buffers and images through `access`.
///
/// # Errors
/// As [`load_gltf_with`].
pub fn parse_gltf_with(
    bytes: &[u8],
    path: &Path,
    access: &FileAccess,
) -> Result<LoadedScene, SceneError> {
    let fail = |message: String| SceneError::Gltf {
        path: path.to_path_buf(),
        message,
    };
    let invalid = |e: gltf::Error| fail(format!("not a valid glTF file: {e}"));
    let gltf::Gltf { document, blob } = read_gltf(bytes).map_err(|e| match version_one(bytes) {
        true => fail(
            "a glTF 1.0 file: this renderer reads glTF 2.0; convert it first, for \
                     example with `npx gltf-pipeline -i FILE -o FILE.gltf` (gltf-pipeline \
                     upgrades 1.0 files)"
                .into(),
        ),
        false => invalid(e),
    })?;
    // The crate's validation indexes the POSITION accessor before checking that it
    // exists: check first.
    check_attribute_indices(document.as_json()).map_err(fail)?;
    let mut root = document.into_json();
    let unsupported = check_extensions(&mut root).map_err(fail)?;
    let unbounded = fill_position_bounds(&mut root);
    // Materials, the nodes' instancing and the primitives' Draco compression are read
    // from the file's own JSON (see `material`): the `gltf` crate keeps none of them.
    let used = |name: &str| root.extensions_used.iter().any(|e| e == name);
    let raw = used(extensions::gpu_instancing::NAME)
        || extensions::image_sources::NAMES
            .iter()
            .any(|name| used(name))
        || used(extensions::draco::NAME)
        || used(extensions::meshopt::NAME)
        || used(extensions::meshopt::KHR_NAME);
    let RawJson {
        materials: raw_materials,
        instancing,
        draco,
        meshopt,
        image_sources,
    } = if root.materials.is_empty() && !raw {
        RawJson::default()
    } else {
        raw_json(bytes).map_err(invalid)?
    };
    extensions::draco::give_views(&mut root, &draco);
    let (image_fallbacks, image_warnings) =
        extensions::image_sources::use_extension_sources(&mut root, &image_sources);
    let compressed = compressed_views(&mut root, &meshopt).map_err(fail)?;
    let scenes = root.scenes.len();
    let document = Document::from_json(root).map_err(|e| {
        fail(format!(
            "not a valid glTF file: {}",
            invalid_reason(e, scenes)
        ))
    })?;
    check_node_cycles(&document).map_err(fail)?;
    let folder = path.parent().unwrap_or(Path::new("")).to_path_buf();
    let buffers = read_buffers(
        &document,
        blob,
        &folder,
        access,
        &meshopt.fallbacks,
        compressed.len(),
    )
    .and_then(|buffers| decode_views(buffers, &compressed))
    .map_err(fail)?;
    let mut reader = Reader {
        path,
        access,
        folder,
        document: &document,
        buffers,
        scene: SceneDescription::default(),
        options: PartialOptions::default(),
        materials: HashMap::new(),
        images: HashMap::new(),
        warned: Vec::new(),
        points_and_lines: std::collections::BTreeSet::new(),
        camera_found: false,
        worlds: None,
        node_uses: {
            let mut uses = vec![0; document.meshes().len()];
            for mesh in document.nodes().filter_map(|n| n.mesh()) {
                uses[mesh.index()] += 1;
            }
            uses
        },
        instanced: HashMap::new(),
        raw_materials,
        instancing,
        draco,
        image_fallbacks,
        texcoord_sets: Vec::new(),
        problems: MaterialProblems::default(),
    };
    reader.texcoord_sets = material::texcoord_sets(&mut reader);
    for warning in image_warnings {
        reader.warn(warning);
    }
    for name in unsupported {
        reader.warn(format!(
            "extension {name} is not supported; the file is read without it"
        ));
    }
    if unbounded > 0 {
        reader.warn(format!(
            "{unbounded} POSITION accessor(s) without the 'min' and 'max' the glTF spec \
             requires; read anyway (as three.js and Blender do)"
        ));
    }
    reader.read_scene().map_err(fail)?;
    reader.warn_points_and_lines();
    let animations = document.animations().len();
    if animations > 0 {
        reader.warn(format!(
            "{animations} animation(s) not played: the nodes' default pose is rendered"
        ));
    }
    finite::drop_non_finite_triangles(&mut reader.scene, path);
    for message in reader.problems.messages() {
        reader.warn(message);
    }
    // As the OBJ reader: texture coordinate indices only where a map can use them.
    if !reader.scene.materials.iter().any(Material::needs_texcoords) {
        reader.scene.triangle_texcoords = Vec::new();
    }
    Ok(LoadedScene {
        description: reader.scene,
        options: reader.options,
    })
}

/// Checks the extensions the file uses against those this reader implements
/// ([`extensions::supported`]). Returns those it uses but this reader does not read,
/// for one warning each.
///
/// # Errors
/// Names an extension the file requires that this reader does not implement (such
/// as `EXT_meshopt_compression`, `KHR_mesh_quantization` or `KHR_texture_basisu`).
/// Required extensions that are implemented are taken off the list the `gltf` crate
/// validates, which knows only those it has types for.
fn check_extensions(root: &mut gltf::json::Root) -> Result<Vec<String>, String> {
    if let Some(name) = root
        .extensions_required
        .iter()
        .find(|name| !extensions::supported(name))
    {
        return Err(format!(
            "the file requires extension {name}, which this renderer does not support"
        ));
    }
    root.extensions_required.clear();
    let mut unsupported: Vec<String> = root
        .extensions_used
        .iter()
        .filter(|name| !extensions::supported(name))
        .cloned()
        .collect();
    unsupported.dedup();
    Ok(unsupported)
}

/// What this reader takes from the file's own JSON (the JSON of a `.gltf`, or the
/// JSON chunk of a `.glb`), since the `gltf` crate keeps none of it.
#[derive(Default)]
struct RawJson {
    /// The JSON object of every material.
    materials: Vec<Value>,
    /// The `EXT_mesh_gpu_instancing` object of each node that has one, by node index.
    instancing: HashMap<usize, Value>,
    /// The `KHR_draco_mesh_compression` object of each primitive that has one, by
    /// mesh and primitive index.
    draco: HashMap<(usize, usize), Value>,
    meshopt: MeshoptJson,
    /// The `EXT_texture_webp` and `KHR_texture_basisu` objects of each texture that
    /// has one, by texture index, with the extension's name, in the order of
    /// [`extensions::image_sources::NAMES`].
    image_sources: Vec<(usize, &'static str, Value)>,
}

/// The `EXT_meshopt_compression` and `KHR_meshopt_compression` objects of a file.
#[derive(Default)]
struct MeshoptJson {
    /// The extension's object of each buffer view that has one, by view index, with
    /// which of the two it is (a view must not have both: KHR's is read).
    views: Vec<(usize, extensions::meshopt::Variant, Value)>,
    /// The buffers marked `"fallback": true`: never read (they may have no `uri`).
    fallbacks: Vec<usize>,
}

/// The extension object `name` of `object`, taken out of it.
fn take_extension(object: &mut Value, name: &str) -> Option<Value> {
    (object.get_mut("extensions"))
        .and_then(|e| e.get_mut(name))
        .map(Value::take)
}

/// The `gltf` crate's document and binary chunk of a `.gltf` or `.glb`, unvalidated.
/// glTF 2.0 lets a scene leave out `nodes` (an empty scene: assimp's test models have
/// one), which the crate requires: a file it refuses is read again with such scenes
/// given no nodes, and its first error stands when that does not help.
fn read_gltf(bytes: &[u8]) -> Result<gltf::Gltf, gltf::Error> {
    gltf::Gltf::from_slice_without_validation(bytes).or_else(|error| {
        let (json, blob) = if bytes.starts_with(b"glTF") {
            let glb = gltf::binary::Glb::from_slice(bytes)?;
            (glb.json, glb.bin.map(std::borrow::Cow::into_owned))
        } else {
            (std::borrow::Cow::Borrowed(bytes), None)
        };
        let Ok(mut root) = gltf::json::deserialize::from_slice::<Value>(&json) else {
            return Err(error);
        };
        let mut added = false;
        if let Some(Value::Array(scenes)) = root.get_mut("scenes") {
            for scene in scenes.iter_mut().filter_map(Value::as_object_mut) {
                if !scene.contains_key("nodes") {
                    scene.insert("nodes".into(), Value::Array(Vec::new()));
                    added = true;
                }
            }
        }
        match gltf::json::deserialize::from_value(root) {
            Ok(root) if added => Ok(gltf::Gltf {
                document: Document::from_json_without_validation(root),
                blob,
            }),
            _ => Err(error),
        }
    })
}

/// Reads [`RawJson`] from the bytes of a `.gltf` or `.glb`.
fn raw_json(bytes: &[u8]) -> Result<RawJson, gltf::Error> {
    let json = if bytes.starts_with(b"glTF") {
        gltf::binary::Glb::from_slice(bytes)?.json
    } else {
        std::borrow::Cow::Borrowed(bytes)
    };
    let mut root: Value =
        gltf::json::deserialize::from_slice(&json).map_err(gltf::Error::Deserialize)?;
    let mut raw = RawJson {
        materials: match root.get_mut("materials").map(Value::take) {
            Some(Value::Array(materials)) => materials,
            _ => Vec::new(),
        },
        ..RawJson::default()
    };
    if let Some(Value::Array(nodes)) = root.get_mut("nodes") {
        for (index, node) in nodes.iter_mut().enumerate() {
            if let Some(extension) = take_extension(node, extensions::gpu_instancing::NAME) {
                raw.instancing.insert(index, extension);
            }
        }
    }
    if let Some(Value::Array(meshes)) = root.get_mut("meshes") {
        for (m, mesh) in meshes.iter_mut().enumerate() {
            if let Some(Value::Array(primitives)) = mesh.get_mut("primitives") {
                for (p, primitive) in primitives.iter_mut().enumerate() {
                    if let Some(extension) = take_extension(primitive, extensions::draco::NAME) {
                        raw.draco.insert((m, p), extension);
                    }
                }
            }
        }
    }
    if let Some(Value::Array(textures)) = root.get_mut("textures") {
        for (index, texture) in textures.iter_mut().enumerate() {
            for name in extensions::image_sources::NAMES {
                if let Some(extension) = take_extension(texture, name) {
                    raw.image_sources.push((index, name, extension));
                }
            }
        }
    }
    use extensions::meshopt::{KHR_NAME, NAME, Variant};
    if let Some(Value::Array(views)) = root.get_mut("bufferViews") {
        for (index, view) in views.iter_mut().enumerate() {
            let ext = take_extension(view, NAME);
            if let Some(khr) = take_extension(view, KHR_NAME) {
                raw.meshopt.views.push((index, Variant::Khr, khr));
            } else if let Some(ext) = ext {
                raw.meshopt.views.push((index, Variant::Ext, ext));
            }
        }
    }
    if let Some(Value::Array(buffers)) = root.get_mut("buffers") {
        for (index, buffer) in buffers.iter_mut().enumerate() {
            let fallback = [NAME, KHR_NAME].iter().any(|name| {
                take_extension(buffer, name)
                    .and_then(|e| e.get("fallback").and_then(Value::as_bool))
                    == Some(true)
            });
            if fallback {
                raw.meshopt.fallbacks.push(index);
            }
        }
    }
    Ok(raw)
}

/// A buffer view to decode: its index and its meshopt extension's object.
struct CompressedView {
    view: usize,
    compressed: extensions::meshopt::Compressed,
}

/// Points each buffer view with `EXT_meshopt_compression` at a buffer of its own,
/// appended to `root`'s (in the order of the views), which [`decode_views`] fills
/// with its decoded data; the view keeps its length, now from byte 0. Returns the
/// views to decode.
///
/// # Errors
/// An extension object that is malformed or breaks the extension's rules (named by
/// its buffer view), or a stream in a buffer that does not exist or is a fallback.
fn compressed_views(
    root: &mut gltf::json::Root,
    meshopt: &MeshoptJson,
) -> Result<Vec<CompressedView>, String> {
    use gltf::json::validation::USize64;
    let buffers = root.buffers.len();
    let mut views = Vec::with_capacity(meshopt.views.len());
    for (index, variant, extension) in &meshopt.views {
        let name = variant.name();
        let fail = |message: String| format!("buffer view {index}: {name}: {message}");
        let compressed =
            extensions::meshopt::Compressed::parse(extension, *variant).map_err(fail)?;
        if compressed.buffer >= buffers {
            return Err(fail(format!(
                "buffer {} does not exist ({buffers} buffers)",
                compressed.buffer
            )));
        }
        if meshopt.fallbacks.contains(&compressed.buffer) {
            return Err(fail(format!(
                "its stream is in buffer {}, a fallback buffer",
                compressed.buffer
            )));
        }
        let Some(view) = root.buffer_views.get_mut(*index) else {
            continue;
        };
        // Accessors step through the view by its own stride: the stream's elements
        // must be that size.
        if let Some(stride) = view.byte_stride
            && stride.0 != compressed.byte_stride
        {
            return Err(fail(format!(
                "a byteStride of {}, the buffer view's is {}",
                compressed.byte_stride, stride.0
            )));
        }
        let size = compressed.decoded_size().map_err(fail)?;
        if view.byte_length.0 > size as u64 {
            return Err(fail(format!(
                "it decodes to {size} bytes, less than the view's byteLength of {}",
                view.byte_length.0
            )));
        }
        view.buffer = gltf::json::Index::new((buffers + views.len()) as u32);
        view.byte_offset = Some(USize64(0));
        views.push(CompressedView {
            view: *index,
            compressed,
        });
    }
    for view in &views {
        root.buffers.push(gltf::json::Buffer {
            byte_length: USize64(view.compressed.decoded_size().unwrap_or(0) as u64),
            name: None,
            uri: None,
            extensions: None,
            extras: Default::default(),
        });
    }
    Ok(views)
}

/// Appends the decoded data of each of `views` to `buffers` (the file's own buffers,
/// as [`read_buffers`] read them), as [`compressed_views`] pointed them.
///
/// # Errors
/// A stream outside its buffer, or one the decoder refuses; named by its view.
fn decode_views(
    mut buffers: Vec<Vec<u8>>,
    views: &[CompressedView],
) -> Result<Vec<Vec<u8>>, String> {
    let own = buffers.len();
    for CompressedView { view, compressed } in views {
        let fail = |message: String| {
            let name = compressed.variant().name();
            format!("buffer view {view}: {name}: {message}")
        };
        let source = &buffers[..own][compressed.buffer];
        let decoded = compressed
            .stream(source)
            .and_then(|stream| compressed.decode(stream))
            .map_err(fail)?;
        buffers.push(decoded);
    }
    Ok(buffers)
}

/// The data of every buffer: the GLB's binary chunk, a data URI or a file beside the
/// glTF file; each at least as long as the file says.
///
/// `EXT_meshopt_compression`'s fallback buffers (`fallbacks`) are left empty, and
/// the buffers [`compressed_views`] appended (the last ones) are left out, for
/// [`decode_views`] to fill.
fn read_buffers(
    document: &Document,
    mut blob: Option<Vec<u8>>,
    folder: &Path,
    access: &FileAccess,
    fallbacks: &[usize],
    decoded: usize,
) -> Result<Vec<Vec<u8>>, String> {
    let own = document.buffers().len() - decoded;
    let mut buffers = Vec::with_capacity(own + decoded);
    for buffer in document.buffers().take(own) {
        let index = buffer.index();
        if fallbacks.contains(&index) {
            buffers.push(Vec::new());
            continue;
        }
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => blob.take().ok_or_else(|| {
                format!("buffer {index} refers to the binary chunk, and there is none")
            })?,
            gltf::buffer::Source::Uri(uri) => read_uri(uri, folder, access)
                .map_err(|reason| format!("buffer {index} ('{}'): {reason}", shorten(uri)))?,
        };
        if data.len() < buffer.length() {
            return Err(format!(
                "buffer {index} has {} bytes, the file says {} (truncated?)",
                data.len(),
                buffer.length()
            ));
        }
        buffers.push(data);
    }
    Ok(buffers)
}

/// The bytes a URI names: a base64 data URI, or a file relative to `folder`
/// (percent-encoded, as URIs are).
fn read_uri(uri: &str, folder: &Path, access: &FileAccess) -> Result<Vec<u8>, String> {
    if let Some(data) = uri.strip_prefix("data:") {
        let (_, payload) = data
            .split_once(";base64,")
            .ok_or("a data URI that is not base64")?;
        return decode_base64(payload).ok_or_else(|| "malformed base64 data".into());
    }
    let file = file_of_uri(uri)?;
    let path = folder.join(&file);
    // Regular files only: `/dev/zero` or a FIFO would be read forever.
    access
        .admit(&path)
        .and_then(|()| read_regular_file(&path))
        .map_err(|e| format!("cannot read {}: {e}", file.display()))
}

/// Whether `bytes` hold a glTF 1.0 file: a version 1 GLB, or JSON whose
/// `asset.version` begins with `1`. Asked only once the file failed to read as 2.0.
fn version_one(bytes: &[u8]) -> bool {
    if bytes.starts_with(b"glTF") {
        return bytes.get(4..8) == Some(&1u32.to_le_bytes()[..]);
    }
    let Ok(root) = gltf::json::deserialize::from_slice::<Value>(bytes) else {
        return false;
    };
    // 1.0 files write the version as a string ("1.0") or a number (1).
    match root.get("asset").and_then(|asset| asset.get("version")) {
        Some(Value::String(version)) => version.starts_with('1'),
        Some(Value::Number(version)) => version.as_f64().is_some_and(|v| v < 2.0),
        _ => false,
    }
}

/// Gives the POSITION accessors that lack `min` or `max` placeholder bounds, so that
/// the `gltf` crate's validation accepts them as other readers do (this reader never
/// reads those bounds: it bounds the positions it reads). Returns how many it filled.
fn fill_position_bounds(root: &mut gltf::json::Root) -> usize {
    let mut filled = 0;
    let positions: Vec<usize> = root
        .meshes
        .iter()
        .flat_map(|mesh| &mesh.primitives)
        .filter_map(|primitive| {
            let key = gltf::json::validation::Checked::Valid(gltf::Semantic::Positions);
            primitive.attributes.get(&key).map(|a| a.value())
        })
        .collect();
    for index in positions {
        let Some(accessor) = root.accessors.get_mut(index) else {
            continue;
        };
        if accessor.min.is_none() || accessor.max.is_none() {
            let zero = || Some(Value::from(vec![0.0; 3]));
            accessor.min = accessor.min.take().or_else(zero);
            accessor.max = accessor.max.take().or_else(zero);
            filled += 1;
        }
    }
    filled
}

/// Every attribute and index accessor of every primitive exists.
fn check_attribute_indices(root: &gltf::json::Root) -> Result<(), String> {
    let count = root.accessors.len();
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            let indices = primitive.indices.iter();
            for accessor in primitive.attributes.values().chain(indices) {
                if accessor.value() >= count {
                    return Err(format!(
                        "mesh {m} primitive {p}: accessor {} does not exist ({count} accessors)",
                        accessor.value()
                    ));
                }
            }
        }
    }
    Ok(())
}

/// The node hierarchy has no cycle (checked over every node, without recursion).
///
/// # Errors
/// Names a node that is its own descendant.
fn check_node_cycles(document: &Document) -> Result<(), String> {
    const NEW: u8 = 0;
    const ON_PATH: u8 = 1;
    const DONE: u8 = 2;
    let nodes: Vec<gltf::Node<'_>> = document.nodes().collect();
    let mut state = vec![NEW; nodes.len()];
    // (node, how many of its children have been looked at)
    let mut path: Vec<(usize, usize)> = Vec::new();
    for start in 0..nodes.len() {
        if state[start] != NEW {
            continue;
        }
        state[start] = ON_PATH;
        path.push((start, 0));
        while let Some((node, next)) = path.last_mut() {
            let node = *node;
            match nodes[node].children().nth(*next) {
                Some(child) => {
                    *next += 1;
                    let child = child.index();
                    match state[child] {
                        NEW => {
                            state[child] = ON_PATH;
                            path.push((child, 0));
                        }
                        ON_PATH => {
                            return Err(format!(
                                "{} is its own descendant: the node hierarchy has a cycle",
                                describe_node(&nodes[child])
                            ));
                        }
                        _ => {}
                    }
                }
                None => {
                    state[node] = DONE;
                    path.pop();
                }
            }
        }
    }
    Ok(())
}

/// `node 3` or `node 3 ('Arm')`, for messages.
fn describe_node(node: &gltf::Node<'_>) -> String {
    match node.name() {
        Some(name) => format!("node {} ('{}')", node.index(), shorten(name)),
        None => format!("node {}", node.index()),
    }
}

/// What a primitive may hold in an accessor: the component types and the shape.
struct Expected {
    what: &'static str,
    types: &'static [gltf::accessor::DataType],
    dimensions: gltf::accessor::Dimensions,
}

/// Floats, or (`KHR_mesh_quantization`) 8- and 16-bit integers, normalized or not.
const QUANTIZED: &[gltf::accessor::DataType] = &[
    gltf::accessor::DataType::F32,
    gltf::accessor::DataType::I8,
    gltf::accessor::DataType::U8,
    gltf::accessor::DataType::I16,
    gltf::accessor::DataType::U16,
];
const POSITIONS: Expected = Expected {
    what: "POSITION",
    types: QUANTIZED,
    dimensions: gltf::accessor::Dimensions::Vec3,
};
/// `KHR_mesh_quantization` allows normalized signed integers only; an unsigned or
/// unnormalized one is read as such (whatever it gives is normalised by the scene).
const NORMALS: Expected = Expected {
    what: "NORMAL",
    types: QUANTIZED,
    dimensions: gltf::accessor::Dimensions::Vec3,
};
const TEXCOORDS: Expected = Expected {
    what: "TEXCOORD_0",
    types: QUANTIZED,
    dimensions: gltf::accessor::Dimensions::Vec2,
};
/// `KHR_mesh_quantization` allows normalized signed bytes and shorts.
const TANGENTS: Expected = Expected {
    what: "TANGENT",
    types: QUANTIZED,
    dimensions: gltf::accessor::Dimensions::Vec4,
};
/// The names of the texture coordinate sets, for messages about the one read.
const TEXCOORD_NAMES: [&str; 4] = ["TEXCOORD_0", "TEXCOORD_1", "TEXCOORD_2", "TEXCOORD_3"];

/// The values of an attribute `accessor` (checked by [`check_accessor`]) as floats:
/// integer components (core glTF's normalized texture coordinates, and every
/// attribute under `KHR_mesh_quantization`) as glTF reads them, normalized ones
/// divided by their type's maximum (signed ones no less than -1), others as they
/// are. `None` for another component type.
fn read_floats<const N: usize>(
    accessor: gltf::Accessor<'_>,
    buffers: &[Vec<u8>],
) -> Option<Vec<[f32; N]>>
where
    [f32; N]: gltf::accessor::Item,
    [i8; N]: gltf::accessor::Item,
    [u8; N]: gltf::accessor::Item,
    [i16; N]: gltf::accessor::Item,
    [u16; N]: gltf::accessor::Item,
{
    use gltf::accessor::DataType;
    fn convert<T: Copy, const N: usize>(
        accessor: gltf::Accessor<'_>,
        buffers: &[Vec<u8>],
        to_float: impl Fn(T) -> f32,
    ) -> Option<Vec<[f32; N]>>
    where
        [T; N]: gltf::accessor::Item,
    {
        let values = gltf::accessor::Iter::<[T; N]>::new(accessor, |buffer| {
            buffers.get(buffer.index()).map(Vec::as_slice)
        })?;
        Some(values.map(|v| v.map(&to_float)).collect())
    }
    let normalized = accessor.normalized();
    let scale = move |value: f32, max: f32| match normalized {
        true => (value / max).max(-1.0),
        false => value,
    };
    match accessor.data_type() {
        DataType::F32 => convert::<f32, N>(accessor, buffers, |x| x),
        DataType::I8 => convert::<i8, N>(accessor, buffers, |x| scale(x as f32, 127.0)),
        DataType::U8 => convert::<u8, N>(accessor, buffers, |x| scale(x as f32, 255.0)),
        DataType::I16 => convert::<i16, N>(accessor, buffers, |x| scale(x as f32, 32767.0)),
        DataType::U16 => convert::<u16, N>(accessor, buffers, |x| scale(x as f32, 65535.0)),
        DataType::U32 => None,
    }
}
const INDICES: Expected = Expected {
    what: "indices",
    types: &[
        gltf::accessor::DataType::U8,
        gltf::accessor::DataType::U16,
        gltf::accessor::DataType::U32,
    ],
    dimensions: gltf::accessor::Dimensions::Scalar,
};

/// Why an accessor cannot be read as `expected`.
enum AccessorProblem {
    /// Another component type or shape: the reader can skip the attribute.
    Type(String),
    /// Its data lies outside its view or buffer, or it has no data: the file is broken.
    Bounds(String),
}

/// Checks an accessor against `expected`, and its data against its buffer view and
/// the view against its buffer (as the `gltf` crate's reader does not: it would
/// panic or wrap around on a count of zero or one that overflows), before any of it
/// is read or anything is allocated for it.
fn check_accessor(
    accessor: &gltf::Accessor<'_>,
    expected: &Expected,
    buffers: &[Vec<u8>],
) -> Result<(), AccessorProblem> {
    let name = format!("accessor {} ({})", accessor.index(), expected.what);
    if !expected.types.contains(&accessor.data_type())
        || accessor.dimensions() != expected.dimensions
    {
        return Err(AccessorProblem::Type(format!(
            "{name}: {:?} {:?} components, expected {:?} of {:?}",
            accessor.dimensions(),
            accessor.data_type(),
            expected.dimensions,
            expected.types
        )));
    }
    let bounds = |message: String| AccessorProblem::Bounds(format!("{name}: {message}"));
    let count = accessor.count();
    if count == 0 {
        return Err(bounds("a count of 0".into()));
    }
    let element = accessor.size();
    match accessor.view() {
        Some(view) => {
            let stride = view.stride().unwrap_or(element);
            if stride < element {
                return Err(bounds(format!(
                    "a byte stride of {stride}, less than its elements' {element} bytes"
                )));
            }
            check_span(&view, accessor.offset(), count, stride, element, buffers)
                .map_err(bounds)?;
        }
        None => {
            // Zeros, then the sparse values: no bigger than the file's buffers (or
            // 1 MiB), so that a small file cannot ask for gigabytes of zeros.
            let held = buffers.iter().map(Vec::len).sum::<usize>().max(1 << 20);
            if count.checked_mul(element).is_none_or(|bytes| bytes > held) {
                return Err(bounds(format!(
                    "{count} elements without a buffer view, more than the file's buffers hold"
                )));
            }
        }
    }
    if let Some(sparse) = accessor.sparse() {
        let n = sparse.count();
        if n == 0 || n > count {
            return Err(bounds(format!("{n} sparse values for {count} elements")));
        }
        let indices = sparse.indices();
        let index_size = match indices.index_type() {
            gltf::accessor::sparse::IndexType::U8 => 1,
            gltf::accessor::sparse::IndexType::U16 => 2,
            gltf::accessor::sparse::IndexType::U32 => 4,
        };
        let view = indices.view();
        let stride = view.stride().unwrap_or(index_size).max(index_size);
        check_span(&view, indices.offset(), n, stride, index_size, buffers)
            .map_err(|e| bounds(format!("sparse indices: {e}")))?;
        let values = sparse.values();
        let view = values.view();
        let stride = view.stride().unwrap_or(element).max(element);
        check_span(&view, values.offset(), n, stride, element, buffers)
            .map_err(|e| bounds(format!("sparse values: {e}")))?;
    }
    Ok(())
}

/// Checks that `count` elements of `element` bytes, `stride` apart from `offset` in
/// `view`, lie inside the view, and the view inside its buffer.
fn check_span(
    view: &gltf::buffer::View<'_>,
    offset: usize,
    count: usize,
    stride: usize,
    element: usize,
    buffers: &[Vec<u8>],
) -> Result<(), String> {
    let buffer = buffers.get(view.buffer().index()).map_or(0, Vec::len);
    let view_end = view.offset().checked_add(view.length());
    if view_end.is_none_or(|end| end > buffer) {
        return Err(format!(
            "buffer view {} ({} bytes from byte {}) lies outside its buffer of {buffer} bytes",
            view.index(),
            view.length(),
            view.offset()
        ));
    }
    let end = (count - 1)
        .checked_mul(stride)
        .and_then(|span| span.checked_add(offset))
        .and_then(|span| span.checked_add(element));
    if end.is_none_or(|end| end > view.length()) {
        return Err(format!(
            "{count} elements from byte {offset} do not fit in buffer view {} of {} bytes",
            view.index(),
            view.length()
        ));
    }
    Ok(())
}

/// The relative path a (non-data) URI names.
fn file_of_uri(uri: &str) -> Result<PathBuf, String> {
    if uri.contains("://") && !uri.starts_with("file://") {
        return Err("only data URIs and relative file names are supported".into());
    }
    let uri = uri.strip_prefix("file://").unwrap_or(uri);
    percent_decode(uri)
        .map(PathBuf::from)
        .ok_or_else(|| "malformed percent-encoding".into())
}

/// A URI for a message: data URIs can be megabytes long.
fn shorten(uri: &str) -> String {
    match uri.char_indices().nth(60) {
        Some((cut, _)) => format!("{}...", &uri[..cut]),
        None => uri.to_owned(),
    }
}

/// Decodes `%XX` escapes; `None` if one is malformed or the result is not UTF-8.
fn percent_decode(text: &str) -> Option<String> {
    let bytes = text.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = std::str::from_utf8(bytes.get(i + 1..i + 3)?).ok()?;
            out.push(u8::from_str_radix(hex, 16).ok()?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).ok()
}

/// Standard base64 (padding optional, whitespace skipped); `None` on any other
/// character.
fn decode_base64(text: &str) -> Option<Vec<u8>> {
    let value = |c: u8| -> Option<u32> {
        Some(match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' | b'-' => 62,
            b'/' | b'_' => 63,
            _ => return None,
        } as u32)
    };
    let mut out = Vec::with_capacity(text.len() / 4 * 3);
    let mut bits = 0u32;
    let mut count = 0;
    for &c in text.as_bytes() {
        if c == b'=' {
            break;
        }
        if c.is_ascii_whitespace() {
            continue;
        }
        bits = (bits << 6) | value(c)?;
        count += 1;
        if count == 4 {
            out.extend_from_slice(&bits.to_be_bytes()[1..]);
            (bits, count) = (0, 0);
        }
    }
    match count {
        0 => {}
        2 => out.push((bits >> 4) as u8),
        3 => out.extend_from_slice(&((bits >> 2) as u16).to_be_bytes()),
        _ => return None,
    }
    Some(out)
}

struct Reader<'a> {
    path: &'a Path,
    /// Where images may be read from.
    access: &'a FileAccess,
    folder: PathBuf,
    document: &'a Document,
    buffers: Vec<Vec<u8>>,
    scene: SceneDescription,
    options: PartialOptions,
    /// Material id of each glTF material (`None`: the default material) used so far.
    materials: HashMap<Option<usize>, MaterialId>,
    /// Each image decoded so far, or why it could not be.
    images: HashMap<usize, Option<Arc<Texture>>>,
    /// The kinds of warning already given, so that each is given once.
    warned: Vec<&'static str>,
    /// The primitives of points or lines met (mesh and primitive), skipped: a set,
    /// since nodes sharing a mesh meet its primitives again.
    points_and_lines: std::collections::BTreeSet<(usize, usize)>,
    camera_found: bool,
    /// Every node's world transform in the default pose, once a skin needs them.
    worlds: Option<Vec<Mat4>>,
    /// How many nodes use each mesh: a mesh of more than one is read once and
    /// placed by instances.
    node_uses: Vec<usize>,
    /// The index in [`SceneDescription::meshes`] of each such mesh read so far, by
    /// the mesh and the morph weights it was posed with (the bits of each): nodes
    /// that share a mesh may pose it differently.
    instanced: HashMap<(usize, Vec<u32>), u32>,
    /// The JSON object of each material.
    raw_materials: Vec<Value>,
    /// The `EXT_mesh_gpu_instancing` object of each node that has one.
    instancing: HashMap<usize, Value>,
    /// The `KHR_draco_mesh_compression` object of each primitive that has one, by
    /// mesh and primitive index.
    draco: HashMap<(usize, usize), Value>,
    /// The texture coordinate set each material's textures are read with, by
    /// material index ([`material::texcoord_sets`]).
    texcoord_sets: Vec<u32>,
    /// The core image of each texture read from its `EXT_texture_webp` or
    /// `KHR_texture_basisu` image, by texture index: read if that image cannot be.
    image_fallbacks: HashMap<usize, usize>,
    /// Problems of the materials' values, for one warning per kind.
    problems: MaterialProblems,
}

impl Reader<'_> {
    fn warn(&mut self, message: String) {
        self.scene
            .warnings
            .push(format!("{}: {message}", self.path.display()));
    }

    /// One warning for the primitives of points and lines skipped, naming the first
    /// (by mesh and primitive index) and counting the others.
    fn warn_points_and_lines(&mut self) {
        let Some(&(mesh, primitive)) = self.points_and_lines.first() else {
            return;
        };
        let more = match self.points_and_lines.len() - 1 {
            0 => String::new(),
            1 => " and 1 more".into(),
            n => format!(" and {n} more"),
        };
        self.warn(format!(
            "mesh {mesh} primitive {primitive}{more}: points and lines are not rendered; skipped"
        ));
    }

    fn warn_once(&mut self, kind: &'static str, message: String) {
        if !self.warned.contains(&kind) {
            self.warned.push(kind);
            self.warn(message);
        }
    }

    /// Walks the default scene (or the first, or with none every root node),
    /// depth first in file order.
    fn read_scene(&mut self) -> Result<(), String> {
        let document = self.document;
        let roots: Vec<gltf::Node<'_>> = match document
            .default_scene()
            .or_else(|| document.scenes().next())
        {
            Some(scene) => scene.nodes().collect(),
            None => {
                let mut is_child = vec![false; document.nodes().len()];
                for node in document.nodes() {
                    for child in node.children() {
                        is_child[child.index()] = true;
                    }
                }
                document.nodes().filter(|n| !is_child[n.index()]).collect()
            }
        };
        let mut visited = vec![false; document.nodes().len()];
        // An explicit stack, not recursion: a hierarchy may be 100,000 levels deep.
        let mut pending: Vec<(gltf::Node<'_>, Mat4)> = roots
            .into_iter()
            .rev()
            .map(|node| (node, Mat4::IDENTITY))
            .collect();
        while let Some((node, parent)) = pending.pop() {
            // Node graphs must be trees (cycles were refused); a node with two
            // parents is read the first time only.
            if std::mem::replace(&mut visited[node.index()], true) {
                self.warn_once(
                    "node twice",
                    format!(
                        "node {} is reached twice in the node tree; read once",
                        node.index()
                    ),
                );
                continue;
            }
            let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
            if !world.is_finite() {
                self.warn(format!(
                    "node {}: a transform that is not finite; skipped",
                    node.index()
                ));
                continue;
            }
            // A skinned mesh is placed by its joints alone (its node's transform is
            // ignored, as glTF says), so always as an object of its own.
            let skin = match (node.mesh(), node.skin()) {
                (Some(_), Some(skin)) => self.skin_matrices(&skin, &node),
                _ => None,
            };
            if let Some(mesh) = node.mesh() {
                // A skinned mesh is placed by its joints, never instanced.
                let unskinned = skin.is_none();
                if let Some(extension) = (self.instancing.get(&node.index())).filter(|_| unskinned)
                {
                    // Its instances place the mesh, each an object.
                    let placements =
                        extensions::gpu_instancing::placements(document, &self.buffers, extension)
                            .map_err(|e| {
                                let name = extensions::gpu_instancing::NAME;
                                format!("{}: {name}: {e}", describe_node(&node))
                            })?;
                    let placements: Vec<Mat4> = placements.iter().map(|p| world * *p).collect();
                    self.add_instances(&mesh, &placements, &node)?;
                } else if unskinned && self.node_uses.get(mesh.index()).is_some_and(|&n| n > 1) {
                    // A copy of a shared mesh: its instance is its object.
                    self.add_instances(&mesh, &[world], &node)?;
                } else {
                    // Each other node with a mesh is an object (the `object_id` output).
                    let name = node
                        .name()
                        .map_or_else(|| format!("node {}", node.index()), String::from);
                    let object = crate::description::ObjectDesc::next_in(&self.scene, name);
                    self.scene.objects.push(object);
                    let weights = node.weights().or(mesh.weights());
                    self.add_mesh(&mesh, &world, weights, skin.as_deref())?;
                }
            }
            if let Some(camera) = node.camera() {
                self.add_camera(&camera, &world);
            }
            if let Some(light) = node.light() {
                self.add_light(&light, &world);
            }
            let first_child = pending.len();
            pending.extend(node.children().map(|child| (child, world)));
            pending[first_child..].reverse();
        }
        Ok(())
    }

    /// Places copies of `mesh` (which several nodes use, or `node`'s instancing
    /// places) by each of `placements`: the mesh is read once (the first time) into
    /// [`SceneDescription::meshes`], in its own space, once for each set of morph
    /// weights its nodes pose it with. Placements that are not
    /// invertible affine maps (a zero scale hides an instance) are skipped, with one
    /// warning for the node.
    fn add_instances(
        &mut self,
        mesh: &gltf::Mesh<'_>,
        placements: &[Mat4],
        node: &gltf::Node<'_>,
    ) -> Result<(), String> {
        // The node's weights replace the mesh's; they matter only to morph targets.
        let morphed = mesh
            .primitives()
            .any(|p| p.morph_targets().next().is_some());
        let weights = node.weights().or(mesh.weights()).filter(|_| morphed);
        let key = (
            mesh.index(),
            weights
                .unwrap_or_default()
                .iter()
                .map(|w| w.to_bits())
                .collect(),
        );
        let index = match self.instanced.get(&key) {
            Some(&index) => index,
            None => {
                let scene = &self.scene;
                let before = (
                    scene.positions.len(),
                    scene.normals.len(),
                    scene.texcoords.len(),
                    scene.triangles.len(),
                );
                self.add_mesh(mesh, &Mat4::IDENTITY, weights, None)?;
                let index = self.scene.meshes.len() as u32;
                let read = split_off_mesh(&mut self.scene, before);
                self.scene.meshes.push(read);
                self.instanced.insert(key, index);
                index
            }
        };
        let (mut skipped, mut problem) = (0, None);
        for world in placements {
            let rows = world.transpose().to_cols_array().map(f64::from);
            match super::compose::affine_from_rows(&rows) {
                Ok(placement) => self.scene.add_instance(index, placement, true),
                Err(message) => {
                    skipped += 1;
                    problem.get_or_insert(message);
                }
            }
        }
        if let Some(message) = problem {
            let node = describe_node(node);
            self.warn(match placements.len() {
                1 => format!("{node}: {message}; skipped"),
                n => {
                    format!("{node}: {skipped} of its {n} instances skipped (the first: {message})")
                }
            });
        }
        Ok(())
    }

    /// Decodes `primitive`'s `KHR_draco_mesh_compression` object `extension`: its
    /// buffer view checked against its buffer, its counts against the accessors'.
    fn decode_draco(
        &self,
        primitive: &gltf::Primitive<'_>,
        extension: &Value,
        texcoord_set: u32,
    ) -> Result<extensions::draco::Decoded, String> {
        let name = extensions::draco::NAME;
        let index = (extension.get("bufferView").and_then(Value::as_u64))
            .ok_or_else(|| format!("{name}: no 'bufferView'"))?;
        let view = usize::try_from(index)
            .ok()
            .and_then(|i| self.document.views().nth(i))
            .ok_or_else(|| format!("{name}: buffer view {index} does not exist"))?;
        let bytes = (self.buffers.get(view.buffer().index()))
            .and_then(|b| b.get(view.offset()..view.offset().checked_add(view.length())?))
            .ok_or_else(|| format!("{name}: buffer view {index} lies outside its buffer"))?;
        let vertices = primitive
            .get(&gltf::Semantic::Positions)
            .ok_or_else(|| format!("{name}: no POSITION accessor"))?
            .count();
        let declared = extensions::draco::Declared {
            vertices,
            indices: primitive.indices().map(|a| a.count()),
            texcoord: format!("TEXCOORD_{texcoord_set}"),
        };
        extensions::draco::decode(extension, bytes, &declared)
    }

    /// The skinning matrix of each of `skin`'s joints in the nodes' default pose, or
    /// `None` with one warning (the mesh is then placed by its node, unskinned).
    fn skin_matrices(&mut self, skin: &gltf::Skin<'_>, node: &gltf::Node<'_>) -> Option<Vec<Mat4>> {
        let worlds = self
            .worlds
            .get_or_insert_with(|| pose::node_worlds(self.document));
        match pose::joint_matrices(skin, worlds, &self.buffers) {
            Ok(matrices) => Some(matrices),
            Err(message) => {
                self.warn_once(
                    "skin",
                    format!(
                        "{}: skin {}: {message}; the mesh is placed by its node, unskinned",
                        describe_node(node),
                        skin.index()
                    ),
                );
                None
            }
        }
    }

    /// Reads `mesh`'s primitives placed by `world`, or, given the `skin`'s joint
    /// matrices, by its joints (each vertex by its own blend of them), with its
    /// morph targets blended by `weights` first.
    fn add_mesh(
        &mut self,
        mesh: &gltf::Mesh<'_>,
        world: &Mat4,
        weights: Option<&[f32]>,
        skin: Option<&[Mat4]>,
    ) -> Result<(), String> {
        // Normals go through the inverse transpose; a mirroring transform turns the
        // winding around, which glTF says to undo.
        let linear = Mat3::from_mat4(*world);
        let normal_matrix = linear.inverse().transpose();
        let mirrored = linear.determinant() < 0.0;
        for primitive in mesh.primitives() {
            let name = format!("mesh {} primitive {}", mesh.index(), primitive.index());
            use gltf::mesh::Mode;
            let mode = primitive.mode();
            if !matches!(
                mode,
                Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
            ) {
                // Told once for the file, counted (`Reader::warn_points_and_lines`).
                self.points_and_lines
                    .insert((mesh.index(), primitive.index()));
                continue;
            }
            // The texture coordinates its material's textures use (one set a
            // primitive: see `material::texcoord_sets`); TEXCOORD_0 if it has not
            // that set.
            let mut set = (primitive.material().index())
                .and_then(|m| self.texcoord_sets.get(m).copied())
                .unwrap_or(0);
            if set != 0 && primitive.get(&gltf::Semantic::TexCoords(set)).is_none() {
                self.warn_once(
                    "texcoord set missing",
                    format!(
                        "{name}: its material's textures use TEXCOORD_{set}, which it does not have; TEXCOORD_0 is read instead"
                    ),
                );
                set = 0;
            }
            let draco = match self.draco.get(&(mesh.index(), primitive.index())) {
                Some(extension) => Some(
                    self.decode_draco(&primitive, extension, set)
                        .map_err(|e| format!("{name}: {e}"))?,
                ),
                None => None,
            };
            let compressed = draco.is_some();
            let (mut positions, mut normals, texcoords, indices, colours) = match draco {
                Some(d) => {
                    let vec3 = |v: Vec<[f32; 3]>| v.into_iter().map(Vec3::from).collect::<Vec<_>>();
                    let texcoords = d.texcoords.map(|t| {
                        // glTF's v runs down the image; this renderer's runs up.
                        t.into_iter().map(|[u, v]| Vec2::new(u, 1.0 - v)).collect()
                    });
                    let colours = d.colours.map(vec3);
                    (
                        vec3(d.positions),
                        d.normals.map(vec3),
                        texcoords,
                        d.indices,
                        colours,
                    )
                }
                None => {
                    // The accessors are checked before the crate's reader touches them.
                    let checked =
                        |expected: &Expected, accessor: Option<gltf::Accessor<'_>>| match accessor
                            .map(|a| check_accessor(&a, expected, &self.buffers))
                        {
                            None | Some(Ok(())) => Ok(None),
                            Some(Err(AccessorProblem::Type(message))) => Ok(Some(message)),
                            Some(Err(AccessorProblem::Bounds(message))) => {
                                Err(format!("{name}: {message}"))
                            }
                        };
                    let position_type =
                        checked(&POSITIONS, primitive.get(&gltf::Semantic::Positions))?;
                    let normal_type = checked(&NORMALS, primitive.get(&gltf::Semantic::Normals))?;
                    let texcoord_expected = Expected {
                        what: TEXCOORD_NAMES.get(set as usize).unwrap_or(&"TEXCOORD_n"),
                        ..TEXCOORDS
                    };
                    let texcoord_type = checked(
                        &texcoord_expected,
                        primitive.get(&gltf::Semantic::TexCoords(set)),
                    )?;
                    if let Some(message) = checked(&INDICES, primitive.indices())? {
                        return Err(format!("{name}: {message}"));
                    }
                    for message in [&position_type, &normal_type, &texcoord_type]
                        .into_iter()
                        .flatten()
                    {
                        self.warn(format!("{name}: {message}; ignored"));
                    }
                    let buffers = &self.buffers;
                    let reader =
                        primitive.reader(|buffer| buffers.get(buffer.index()).map(Vec::as_slice));
                    let attribute = |semantic: gltf::Semantic, problem: &Option<String>| {
                        primitive.get(&semantic).filter(|_| problem.is_none())
                    };
                    let positions = attribute(gltf::Semantic::Positions, &position_type)
                        .and_then(|a| read_floats::<3>(a, buffers));
                    let Some(positions) = positions else {
                        self.warn(format!("{name}: no readable POSITION; skipped"));
                        continue;
                    };
                    let positions: Vec<Vec3> = positions.into_iter().map(Vec3::from).collect();
                    let count = positions.len();
                    let normals: Option<Vec<Vec3>> =
                        attribute(gltf::Semantic::Normals, &normal_type)
                            .and_then(|a| read_floats::<3>(a, buffers))
                            .map(|n| n.into_iter().map(Vec3::from).collect::<Vec<_>>())
                            .filter(|n| n.len() == count);
                    let texcoords: Option<Vec<Vec2>> =
                        attribute(gltf::Semantic::TexCoords(set), &texcoord_type)
                            .and_then(|a| read_floats::<2>(a, buffers))
                            .map(|t| {
                                // glTF's v runs down the image; this renderer's runs up.
                                t.into_iter()
                                    .map(|[u, v]| Vec2::new(u, 1.0 - v))
                                    .collect::<Vec<_>>()
                            })
                            .filter(|t| t.len() == count);
                    let indices: Vec<u32> = match reader.read_indices() {
                        Some(indices) => indices.into_u32().collect(),
                        None if primitive.indices().is_some() => {
                            return Err(format!(
                                "{name}: the indices' data lies outside its buffer"
                            ));
                        }
                        None => (0..count as u32).collect(),
                    };
                    if let Some(&bad) = indices.iter().find(|&&i| i as usize >= count) {
                        return Err(format!(
                            "{name}: index {bad} out of range ({count} vertices)"
                        ));
                    }
                    let colours: Option<Vec<Vec3>> = reader
                        .read_colors(0)
                        .map(|c| c.into_rgb_f32().map(Vec3::from).collect::<Vec<_>>())
                        .filter(|c| c.len() == count);
                    (positions, normals, texcoords, indices, colours)
                }
            };
            let count = positions.len();
            // Blended morph targets move the normals and tangents: the file's tangents
            // are then not read (MikkTSpace's are made for the posed mesh).
            let mut morphed = false;
            if let Some(weights) = weights.filter(|w| w.iter().any(|&w| w != 0.0))
                && primitive.morph_targets().next().is_some()
            {
                morphed = true;
                let blended = match compressed {
                    true => Err("a Draco-compressed primitive's morph targets are not read".into()),
                    false => pose::morph(
                        &primitive,
                        weights,
                        &mut positions,
                        normals.as_deref_mut(),
                        &self.buffers,
                    ),
                };
                if let Err(message) = blended {
                    self.warn_once(
                        "morph",
                        format!("{name}: {message}; the mesh is read without its morph targets"),
                    );
                }
            }
            // Each vertex's own placement when a skin places the mesh.
            let skinned = skin.and_then(|matrices| {
                let placements = match compressed {
                    true => Err("a Draco-compressed primitive's joints are not read".into()),
                    false => {
                        pose::vertex_matrices(&primitive, matrices, count, *world, &self.buffers)
                    }
                };
                match placements {
                    Ok(placements) => Some(placements),
                    Err(message) => {
                        self.warn_once(
                            "skin",
                            format!("{name}: {message}; the mesh is placed by its node, unskinned"),
                        );
                        None
                    }
                }
            });
            // A buffer may hold NaN, and a huge transform may overflow: the triangles
            // at such positions are dropped once the file is read (`formats::finite`).
            // Normals that are not finite (in the file, or once placed by a singular
            // transform) and texture coordinates that are not finite are taken from
            // the triangles using them once the file is read, as positions are.
            let (positions, normals, mirrored_at): (Vec<Vec3>, Option<Vec<Vec3>>, Vec<bool>) =
                match &skinned {
                    None => (
                        positions
                            .iter()
                            .map(|&p| world.transform_point3(p))
                            .collect(),
                        normals.map(|n| n.iter().map(|&n| normal_matrix * n).collect()),
                        Vec::new(),
                    ),
                    Some(placements) => (
                        positions
                            .iter()
                            .zip(placements)
                            .map(|(&p, m)| m.transform_point3(p))
                            .collect(),
                        normals.map(|n| {
                            n.iter()
                                .zip(placements)
                                .map(|(&n, m)| pose::normal_matrix(m) * n)
                                .collect()
                        }),
                        placements
                            .iter()
                            .map(|m| Mat3::from_mat4(*m).determinant() < 0.0)
                            .collect(),
                    ),
                };
            let colours = match colours {
                Some(c) if c.iter().any(|c| !c.is_finite()) => {
                    self.warn(format!(
                        "{name}: vertex colours that are not finite; ignored"
                    ));
                    None
                }
                other => other,
            };
            let material = self.material(primitive.material());
            // The file's tangents, placed as the normals are, only where the material
            // reads a tangent frame and the vertices have normals (glTF: without
            // normals, tangents are ignored).
            let tangents = match normals.is_some()
                && !compressed
                && !morphed
                && self.scene.materials[material.0 as usize].needs_tangents()
            {
                true => self
                    .read_tangents(&primitive, &name, count)
                    .map(|tangents| {
                        let place = |m: &Mat3, t: Vec4| {
                            let sign = if m.determinant() < 0.0 { -1.0 } else { 1.0 };
                            (*m * t.truncate()).extend(t.w * sign)
                        };
                        match &skinned {
                            None => tangents.into_iter().map(|t| place(&linear, t)).collect(),
                            Some(placements) => (tangents.into_iter().zip(placements))
                                .map(|(t, m)| place(&Mat3::from_mat4(*m), t))
                                .collect::<Vec<_>>(),
                        }
                    }),
                false => None,
            };
            if mode == Mode::Triangles && indices.len() % 3 != 0 {
                let (what, count) = match primitive.indices() {
                    Some(_) => ("indices", indices.len()),
                    None => ("vertices", count),
                };
                self.warn_once(
                    "incomplete triangle",
                    format!(
                        "{name}: {count} {what} for TRIANGLES, not a multiple of 3; the last {} skipped",
                        match count % 3 {
                            1 => "one is",
                            _ => "two are",
                        }
                    ),
                );
            }
            let triangles = triangles(mode, &indices);
            let base = |len: usize| -> Result<u32, String> {
                u32::try_from(len + count)
                    .map(|_| len as u32)
                    .map_err(|_| "more vertices than 32-bit indices can address".to_string())
            };
            let position_base = base(self.scene.positions.len())?;
            let normal_base = base(self.scene.normals.len())?;
            let texcoord_base = base(self.scene.texcoords.len())?;
            let scene = &mut self.scene;
            if let Some(colours) = &colours {
                scene.set_colours(position_base as usize, colours);
            }
            scene.positions.extend(positions);
            let has_normals = normals.is_some();
            if let Some(normals) = normals {
                scene.normals.extend(normals);
                if let Some(tangents) = &tangents {
                    scene.set_tangents(normal_base as usize, tangents);
                }
            }
            let has_texcoords = texcoords.is_some();
            if let Some(texcoords) = texcoords {
                scene.texcoords.extend(texcoords);
            }
            for [a, b, c] in triangles {
                let turned = mirrored_at.get(a as usize).copied().unwrap_or(mirrored);
                let corners = if turned { [a, c, b] } else { [a, b, c] };
                scene.push_triangle(
                    TriangleDesc {
                        positions: corners.map(|i| position_base + i),
                        material,
                    },
                    has_normals.then(|| corners.map(|i| normal_base + i)),
                );
                let texcoords = has_texcoords.then(|| corners.map(|i| texcoord_base + i));
                scene.triangle_texcoords.push(texcoords);
            }
        }
        Ok(())
    }

    /// `primitive`'s `TANGENT` (float, or normalized integers under
    /// `KHR_mesh_quantization`), `w` read as its sign; `None` when it has none, or
    /// with one warning per kind when it cannot be used (another type, a count that
    /// is not `count`, a value that is not finite or a zero direction): its tangents
    /// are then made by MikkTSpace, as for a primitive without them.
    fn read_tangents(
        &mut self,
        primitive: &gltf::Primitive<'_>,
        name: &str,
        count: usize,
    ) -> Option<Vec<Vec4>> {
        let accessor = primitive.get(&gltf::Semantic::Tangents)?;
        let instead = "its tangents are made by MikkTSpace instead";
        if let Err(AccessorProblem::Type(message) | AccessorProblem::Bounds(message)) =
            check_accessor(&accessor, &TANGENTS, &self.buffers)
        {
            self.warn_once("tangent type", format!("{name}: {message}; {instead}"));
            return None;
        }
        let values = read_floats::<4>(accessor, &self.buffers).filter(|v| v.len() == count);
        let Some(values) = values else {
            self.warn_once(
                "tangent count",
                format!("{name}: TANGENT not readable or not one a vertex; {instead}"),
            );
            return None;
        };
        if values.iter().flatten().any(|x| !x.is_finite()) {
            self.warn_once(
                "tangent not finite",
                format!("{name}: TANGENT values that are not finite; {instead}"),
            );
            return None;
        }
        if values
            .iter()
            .any(|[x, y, z, _]| [x, y, z].iter().all(|&&c| c == 0.0))
        {
            self.warn_once(
                "tangent zero",
                format!("{name}: TANGENT of zero length; {instead}"),
            );
            return None;
        }
        Some(
            (values.into_iter())
                .map(|[x, y, z, w]| Vec4::new(x, y, z, if w < 0.0 { -1.0 } else { 1.0 }))
                .collect(),
        )
    }

    fn add_camera(&mut self, camera: &gltf::Camera<'_>, world: &Mat4) {
        if self.camera_found {
            return;
        }
        self.camera_found = true;
        let origin = |key| Origin::File {
            path: self.path.to_path_buf(),
            line: 0,
            key,
        };
        // The camera looks down its local -z with +y up.
        let eye = world.transform_point3(Vec3::ZERO);
        let forward = world.transform_vector3(Vec3::NEG_Z);
        let up = world.transform_vector3(Vec3::Y);
        let options = &mut self.options;
        options.look_from = Some(Sourced::new(eye, origin("camera node")));
        options.look_to = Some(Sourced::new(eye + forward, origin("camera node")));
        options.up = Some(Sourced::new(up, origin("camera node")));
        let aspect = match camera.projection() {
            gltf::camera::Projection::Perspective(perspective) => {
                options.fov_degrees = Some(Sourced::new(
                    perspective.yfov().to_degrees(),
                    origin("camera.yfov"),
                ));
                perspective.aspect_ratio()
            }
            // `xmag` and `ymag` are half the view's width and height in the camera's
            // units; the node's scale along y, if any, scales them to the scene's.
            gltf::camera::Projection::Orthographic(ortho) => {
                let half_height = ortho.ymag() * up.length();
                options.projection = Some(Sourced::new(
                    Projection::Orthographic { half_height },
                    origin("camera.ymag"),
                ));
                Some(ortho.xmag() / ortho.ymag())
            }
        };
        if let Some(aspect) = aspect
            && aspect.is_finite()
            && aspect > 0.0
        {
            // The default height, and the width that keeps the camera's aspect ratio.
            let height = i64::from(RenderOptions::default().height);
            let width = (height as Float * aspect).round().max(1.0) as i64;
            options.width = Some(Sourced::new(width, origin("camera.aspectRatio")));
            options.height = Some(Sourced::new(height, origin("camera.aspectRatio")));
        }
    }

    /// A `KHR_lights_punctual` light at its node: placed at the node's origin,
    /// shining along the node's -Z, with its colour times its intensity (candela,
    /// or lux for a directional light) as is, the spot's cone and the range (if
    /// given). Values the extension forbids are warned about, naming the key, and
    /// mended where there is an obvious reading (a cone over 90 degrees is 90, an
    /// inner cone wider than the outer one is the outer one) or the light skipped.
    fn add_light(&mut self, light: &gltf::khr_lights_punctual::Light<'_>, world: &Mat4) {
        use gltf::khr_lights_punctual::Kind;
        let name = format!("light {}", light.index());
        let intensity = Vec3::from(light.color()) * light.intensity();
        if !intensity.is_finite() {
            self.warn(format!("{name}: an intensity that is not finite; skipped"));
            return;
        }
        if light.intensity() < 0.0 || light.color().iter().any(|&c| c < 0.0) {
            self.warn(format!(
                "{name}: intensity: negative light ({} times colour {:?}); skipped",
                light.intensity(),
                light.color()
            ));
            return;
        }
        let direction = world.transform_vector3(Vec3::NEG_Z);
        let direction = match direction.try_normalize() {
            Some(d) => d,
            None if matches!(light.kind(), Kind::Point) => Vec3::NEG_Z,
            None => {
                self.warn(format!(
                    "{name}: its node's transform gives it no direction (a zero scale); skipped"
                ));
                return;
            }
        };
        let kind = match light.kind() {
            Kind::Point => LightKind::Point,
            Kind::Directional => LightKind::Directional { direction },
            Kind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => {
                let right = std::f32::consts::FRAC_PI_2;
                let mut outer = outer_cone_angle;
                if !(outer > 0.0 && outer <= right) {
                    self.warn(format!(
                        "{name}: spot.outerConeAngle: {outer} is not in (0, pi/2]; read as {}",
                        outer.clamp(0.0, right)
                    ));
                    outer = if outer.is_nan() {
                        right
                    } else {
                        outer.clamp(0.0, right)
                    };
                }
                let mut inner = inner_cone_angle;
                if !(inner >= 0.0 && inner <= outer) {
                    let mended = if inner.is_nan() {
                        0.0
                    } else {
                        inner.clamp(0.0, outer)
                    };
                    self.warn(format!(
                        "{name}: spot.innerConeAngle: {inner} is not in [0, outerConeAngle = {outer}]; read as {mended}"
                    ));
                    inner = mended;
                }
                LightKind::Spot {
                    direction,
                    cos_inner: inner.cos(),
                    cos_outer: outer.cos(),
                }
            }
        };
        let range = match light.range() {
            // A directional light is infinitely far away: `range` means nothing.
            Some(_) if matches!(kind, LightKind::Directional { .. }) => None,
            Some(range) if !(range > 0.0 && range.is_finite()) => {
                self.warn(format!(
                    "{name}: range: {range} is not a positive number; the light has no range"
                ));
                None
            }
            range => range,
        };
        self.scene.lights.push(Light {
            position: world.transform_point3(Vec3::ZERO),
            intensity,
            kind,
            range,
        });
    }

    /// The id of glTF material `material` (made on first use).
    fn material(&mut self, material: gltf::Material<'_>) -> MaterialId {
        if let Some(&id) = self.materials.get(&material.index()) {
            return id;
        }
        let made = match material.index() {
            // Primitives without a material: glTF's default is white metal (black in
            // a Phong renderer); the renderer's matte grey shows their shape instead.
            None => Material::fallback(),
            Some(index) => {
                let json = self.raw_materials.get(index).cloned().unwrap_or_default();
                material::convert(self, index, &json)
            }
        };
        let id = MaterialId(self.scene.materials.len() as u32);
        self.scene.materials.push(made);
        self.materials.insert(material.index(), id);
        id
    }
}

/// The geometry appended to `scene` since it held `before` (positions, normals,
/// texture coordinates, triangles) taken out as a mesh of its own, its indices
/// starting from 0: a mesh read once for the instances that place it.
fn split_off_mesh(
    scene: &mut SceneDescription,
    (positions, normals, texcoords, triangles): (usize, usize, usize, usize),
) -> SceneDescription {
    let [p0, n0, t0] = [positions, normals, texcoords].map(|n| n as u32);
    let mut mesh = SceneDescription {
        colours: match scene.colours.len() > positions {
            true => scene.colours.split_off(positions),
            false => Vec::new(),
        },
        positions: scene.positions.split_off(positions),
        tangents: match scene.tangents.len() > normals {
            true => scene.tangents.split_off(normals),
            false => Vec::new(),
        },
        normals: scene.normals.split_off(normals),
        texcoords: scene.texcoords.split_off(texcoords),
        triangles: scene.triangles.split_off(triangles),
        ..SceneDescription::default()
    };
    for t in &mut mesh.triangles {
        t.positions = t.positions.map(|i| i - p0);
    }
    if scene.triangle_normals.len() > triangles {
        mesh.triangle_normals = scene.triangle_normals.split_off(triangles);
        for n in mesh.triangle_normals.iter_mut().flatten() {
            *n = n.map(|i| i - n0);
        }
    }
    if scene.triangle_texcoords.len() > triangles {
        mesh.triangle_texcoords = scene.triangle_texcoords.split_off(triangles);
        for t in mesh.triangle_texcoords.iter_mut().flatten() {
            *t = t.map(|i| i - t0);
        }
    }
    // Flat triangles keep no normal indices when none of them has normals.
    if scene.triangle_normals.iter().all(Option::is_none) {
        scene.triangle_normals.clear();
    }
    mesh
}

/// What the `gltf` crate's validation found wrong, in words: each problem (the first
/// three) as `PATH: WHAT`, where the crate writes `invalid glTF: PATH: Index out of
/// bounds;`. A default `scene` that does not exist (Assimp's `NoScene.gltf`) says how
/// many the file has.
fn invalid_reason(error: gltf::Error, scenes: usize) -> String {
    use gltf::json::validation::Error as Problem;
    let gltf::Error::Validation(problems) = error else {
        return error.to_string();
    };
    let shown = 3;
    let mut parts: Vec<String> = (problems.iter().take(shown))
        .map(|(path, problem)| {
            let path = path.as_str();
            let what = match problem {
                Problem::IndexOutOfBounds if path == "scene" => format!(
                    "no such scene (the file has {scenes} scene{})",
                    if scenes == 1 { "" } else { "s" }
                ),
                Problem::IndexOutOfBounds => "index out of range".into(),
                Problem::Invalid => "invalid value".into(),
                Problem::Missing => "missing".into(),
                Problem::Oversize => "too large for this machine".into(),
                Problem::Unsupported => "not supported".into(),
            };
            format!("{path}: {what}")
        })
        .collect();
    if problems.len() > shown {
        parts.push(format!("and {} more problems", problems.len() - shown));
    }
    parts.join("; ")
}

/// The triangles of a primitive's index list in `mode`, degenerate ones included
/// (the scene drops those).
fn triangles(mode: gltf::mesh::Mode, indices: &[u32]) -> Vec<[u32; 3]> {
    use gltf::mesh::Mode;
    match mode {
        Mode::TriangleStrip => indices
            .windows(3)
            .enumerate()
            // Every other triangle of a strip is wound the other way round.
            .map(|(i, w)| {
                if i % 2 == 0 {
                    [w[0], w[1], w[2]]
                } else {
                    [w[1], w[0], w[2]]
                }
            })
            .collect(),
        Mode::TriangleFan => match indices.split_first() {
            Some((&first, rest)) => rest.windows(2).map(|w| [first, w[0], w[1]]).collect(),
            None => Vec::new(),
        },
        _ => indices
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_decodes_with_and_without_padding() {
        assert_eq!(decode_base64("aGVsbG8=").unwrap(), b"hello");
        assert_eq!(decode_base64("aGVsbG8").unwrap(), b"hello");
        assert_eq!(decode_base64("aGVsbA==").unwrap(), b"hell");
        assert_eq!(decode_base64("").unwrap(), b"");
        assert!(decode_base64("a$==").is_none());
        assert!(decode_base64("a").is_none());
    }

    #[test]
    fn percent_escapes_decode_and_bad_ones_are_refused() {
        assert_eq!(percent_decode("my%20model.bin").unwrap(), "my model.bin");
        assert!(percent_decode("bad%2").is_none());
        assert!(percent_decode("bad%zz").is_none());
    }

    #[test]
    fn strips_and_fans_keep_their_winding() {
        use gltf::mesh::Mode;
        assert_eq!(
            triangles(Mode::TriangleStrip, &[0, 1, 2, 3]),
            vec![[0, 1, 2], [2, 1, 3]]
        );
        assert_eq!(
            triangles(Mode::TriangleFan, &[0, 1, 2, 3]),
            vec![[0, 1, 2], [0, 2, 3]]
        );
        assert_eq!(triangles(Mode::Triangles, &[0, 1, 2, 3]), vec![[0, 1, 2]]);
    }
}
