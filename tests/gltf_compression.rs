//! glTF's compressed geometry: `KHR_draco_mesh_compression`, checked against the
//! uncompressed model (`tests/data/gltf/draco/expected.json`, written by its
//! `make_expected.py` from the uncompressed 2CylinderEngine), and corrupt Draco data;
//! `EXT_meshopt_compression` (with `KHR_mesh_quantization`), checked against the
//! uncompressed torus that `tests/data/gltf/meshopt/make_fixtures.py` wrote and
//! gltfpack compressed, the same files as `KHR_meshopt_compression`, and corrupt
//! meshopt streams of both.

use crate::support;

use std::path::{Path, PathBuf};

use gltf::json::Value;
use raytracer::description::SceneDescription;
use raytracer::formats;
use raytracer::math::{Vec2, Vec3};

fn draco_fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/gltf/draco")
        .join(name)
}

fn expected() -> Value {
    let text = std::fs::read(draco_fixture("expected.json")).unwrap();
    gltf::json::deserialize::from_slice(&text).unwrap()
}

fn vec3(value: &Value) -> Vec3 {
    let v: Vec<f32> = (value.as_array().unwrap().iter())
        .map(|x| x.as_f64().unwrap() as f32)
        .collect();
    Vec3::new(v[0], v[1], v[2])
}

#[test]
fn draco_primitives_decode_to_the_uncompressed_models_triangles_and_bounds() {
    let path = draco_fixture("2CylinderEngine.gltf");
    let mut loaded = formats::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let d = &mut loaded.description;
    d.flatten_instances().unwrap();
    let expected = expected();
    assert_eq!(
        d.triangles.len() as u64,
        expected["triangles"].as_u64().unwrap()
    );
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for t in &d.triangles {
        for i in t.positions {
            let p = d.positions[i as usize];
            (lo, hi) = (lo.min(p), hi.max(p));
        }
    }
    // Positions are quantised (to 11 bits of each primitive's extent): the bounds
    // agree to within one step.
    let tolerance = expected["tolerance"].as_f64().unwrap() as f32;
    let (want_lo, want_hi) = (vec3(&expected["min"]), vec3(&expected["max"]));
    assert!(
        (lo - want_lo).abs().max_element() <= tolerance,
        "min {lo} vs {want_lo} (tolerance {tolerance})"
    );
    assert!(
        (hi - want_hi).abs().max_element() <= tolerance,
        "max {hi} vs {want_hi} (tolerance {tolerance})"
    );
    // Normals were decoded (and dequantised to unit length) with the positions.
    assert!(!d.normals.is_empty());
    for n in &d.normals {
        assert!((n.length() - 1.0).abs() < 0.02, "normal {n}");
    }
}

/// The fixture's JSON, with `edit` applied, written beside `bin` (its buffer) in a
/// fresh folder; the error of loading it, which must name the file.
fn error_of(edit: impl FnOnce(&mut Value), bin: &[u8]) -> String {
    let text = std::fs::read(draco_fixture("2CylinderEngine.gltf")).unwrap();
    let mut json: Value = gltf::json::deserialize::from_slice(&text).unwrap();
    edit(&mut json);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("broken.gltf");
    std::fs::write(&path, gltf::json::serialize::to_vec(&json).unwrap()).unwrap();
    std::fs::write(dir.path().join("2CylinderEngine.bin"), bin).unwrap();
    let error = match formats::load(&path) {
        Ok(_) => panic!("corrupt Draco data was read without an error"),
        Err(e) => e.to_string(),
    };
    assert!(
        error.starts_with(&path.display().to_string()),
        "the error does not name the file: {error}"
    );
    error
}

/// The byte span of the Draco data of mesh 0's primitive 0.
fn first_draco_view(json: &Value) -> (usize, usize) {
    let view =
        json["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]["bufferView"]
            .as_u64()
            .unwrap() as usize;
    let view = &json["bufferViews"][view];
    let offset = view["byteOffset"].as_u64().unwrap_or(0) as usize;
    (offset, view["byteLength"].as_u64().unwrap() as usize)
}

#[test]
fn truncated_or_bit_flipped_draco_data_is_an_error_naming_the_file_and_primitive() {
    let bin = std::fs::read(draco_fixture("2CylinderEngine.bin")).unwrap();
    let text = std::fs::read(draco_fixture("2CylinderEngine.gltf")).unwrap();
    let json: Value = gltf::json::deserialize::from_slice(&text).unwrap();
    let (offset, length) = first_draco_view(&json);
    let view =
        json["meshes"][0]["primitives"][0]["extensions"]["KHR_draco_mesh_compression"]["bufferView"]
            .as_u64()
            .unwrap() as usize;
    // The Draco data cut short, at several lengths.
    for cut in [0, 4, length / 3, length / 2, length - 1] {
        let error = error_of(
            |json| json["bufferViews"][view]["byteLength"] = Value::from(cut.max(1)),
            &bin,
        );
        assert!(
            error.contains("mesh 0 primitive 0: KHR_draco_mesh_compression"),
            "cut at {cut}: {error}"
        );
    }
    // Counts other than the accessors declare.
    let error = error_of(
        |json| {
            let position = json["meshes"][0]["primitives"][0]["attributes"]["POSITION"]
                .as_u64()
                .unwrap() as usize;
            json["accessors"][position]["count"] = Value::from(2020);
        },
        &bin,
    );
    assert!(
        error.contains(
            "mesh 0 primitive 0: KHR_draco_mesh_compression: the Draco data holds 2019 vertices, the POSITION accessor says 2020"
        ),
        "{error}"
    );
    // Bits flipped in the header and the connectivity: errors.
    for at in [0, 7, 8, 12, 176, 352, 880] {
        let mut flipped = bin.clone();
        flipped[offset + at] ^= 0xA5;
        let error = error_of(|_| {}, &flipped);
        assert!(error.contains("mesh 0 primitive 0"), "byte {at}: {error}");
    }
    // Anywhere: an error or other values (Draco has no checksum), never a panic.
    for at in (0..length).step_by(127) {
        let mut flipped = bin.clone();
        flipped[offset + at] ^= 0xA5;
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("a.gltf"), &text).unwrap();
        std::fs::write(dir.path().join("2CylinderEngine.bin"), &flipped).unwrap();
        let result = std::panic::catch_unwind(|| formats::load(&dir.path().join("a.gltf")).err());
        let error = result.unwrap_or_else(|_| panic!("byte {at} flipped: a panic"));
        if let Some(error) = error.map(|e| e.to_string()) {
            assert!(
                error.contains("a.gltf: mesh 0 primitive 0"),
                "byte {at}: {error}"
            );
        }
    }
}

fn meshopt_fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/gltf/meshopt")
        .join(name)
}

/// A loaded file's description, its instances flattened.
fn described(path: &Path) -> SceneDescription {
    let mut loaded = formats::load(path).unwrap_or_else(|e| panic!("{e}"));
    loaded.description.flatten_instances().unwrap();
    loaded.description
}

/// The triangles of `d` as corner positions, each snapped to the nearest of
/// `vertices` (the source's distinct positions, seam copies merged) and rotated to
/// begin at its least corner, winding kept; sorted. Panics when a corner lies
/// farther than `tolerance` from every source position.
fn snapped_triangles(d: &SceneDescription, vertices: &[Vec3], tolerance: f32) -> Vec<[usize; 3]> {
    let snap = |p: Vec3| -> usize {
        let (best, distance) = (vertices.iter().enumerate())
            .map(|(i, v)| (i, v.distance(p)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .unwrap();
        assert!(
            distance <= tolerance,
            "{p} is {distance} from every source vertex"
        );
        best
    };
    let mut triangles: Vec<[usize; 3]> = (d.triangles.iter())
        .map(|t| {
            let [a, b, c] = t.positions.map(|i| snap(d.positions[i as usize]));
            match a.min(b).min(c) {
                m if m == a => [a, b, c],
                m if m == b => [b, c, a],
                _ => [c, a, b],
            }
        })
        .collect();
    triangles.sort_unstable();
    triangles
}

/// The source's distinct positions (its seams' copies merged).
fn distinct_positions(d: &SceneDescription) -> Vec<Vec3> {
    let mut distinct: Vec<Vec3> = Vec::new();
    for &p in &d.positions {
        if distinct.iter().all(|q| q.distance(p) > 1e-5) {
            distinct.push(p);
        }
    }
    distinct
}

/// Each vertex of `d`, by its triangles' corners: (position, normal, texture
/// coordinate).
fn corners(d: &SceneDescription) -> Vec<(Vec3, Vec3, Vec2)> {
    let mut out = Vec::new();
    for (t, triangle) in d.triangles.iter().enumerate() {
        let normals = d.triangle_normals[t].unwrap();
        let texcoords = d.triangle_texcoords[t].unwrap();
        for k in 0..3 {
            out.push((
                d.positions[triangle.positions[k] as usize],
                // Normals are placed by the inverse transpose of the node's
                // transform (gltfpack's dequantizing scale among them), and
                // normalized by the scene.
                d.normals[normals[k] as usize].normalize(),
                d.texcoords[texcoords[k] as usize],
            ));
        }
    }
    out
}

#[test]
fn meshopt_files_decode_to_the_uncompressed_sources_triangles_normals_and_texcoords() {
    let source = described(&meshopt_fixture("torus.glb"));
    let vertices = distinct_positions(&source);
    let source_corners = corners(&source);
    // File, position tolerance (gltfpack's 14-bit integer positions over the torus'
    // 2.8 extent: 1.7e-4 a step; exponential-filtered floats; plain floats),
    // normal tolerance (8-bit and 12-bit octahedral; plain floats), and whether the
    // texture coordinates are the source's as they are (quantized ones are scaled
    // back by KHR_texture_transform when sampled, checked by the render below).
    for (file, position_tolerance, normal_tolerance, plain_texcoords) in [
        ("torus-quantized.glb", 2e-4, 0.02, false),
        ("torus-filters.glb", 1e-4, 2e-3, true),
        ("torus-float.glb", 0.0, 0.0, true),
        // gltfpack's defaults as KHR_meshopt_compression: version 1 vertex streams.
        ("torus-khr.glb", 2e-4, 0.02, false),
    ] {
        let d = described(&meshopt_fixture(file));
        assert_eq!(d.triangles.len(), source.triangles.len(), "{file}");
        // The same triangles (gltfpack reorders vertices and triangles), wound alike.
        assert_eq!(
            snapped_triangles(&d, &vertices, position_tolerance + 1e-6),
            snapped_triangles(&source, &vertices, 1e-5),
            "{file}"
        );
        // Every corner's normal (and texture coordinate) is the source's at that
        // position, within the quantization.
        for (p, n, uv) in corners(&d) {
            let near = (source_corners.iter())
                .filter(|(q, _, _)| q.distance(p) <= position_tolerance + 1e-6);
            let (normal_error, uv_error) = near.fold((f32::MAX, f32::MAX), |(a, b), (_, m, w)| {
                (a.min(m.distance(n)), b.min(w.distance(uv)))
            });
            assert!(
                normal_error <= normal_tolerance + 1e-6,
                "{file}: normal {n} at {p} is {normal_error} from the source's"
            );
            if plain_texcoords {
                assert!(
                    uv_error <= 1e-5,
                    "{file}: texture coordinate {uv} at {p} is {uv_error} from the source's"
                );
            }
        }
    }
}

#[test]
fn meshopt_files_render_as_the_uncompressed_source() {
    let dir = tempfile::tempdir().unwrap();
    let flags = ["--width", "64", "--height", "48"];
    let source = support::render(
        &meshopt_fixture("torus.glb"),
        &dir.path().join("s.png"),
        &flags,
    );
    for file in [
        "torus-quantized.glb",
        "torus-filters.glb",
        "torus-float.glb",
        "torus-khr.glb",
    ] {
        let out = dir.path().join("c.png");
        let image = support::render(&meshopt_fixture(file), &out, &flags);
        // Quantized normals shade a few levels apart, and quantized positions move
        // silhouettes and texture seams by a fraction of a pixel: as many as 1% of
        // the pixels may differ by more than 8 levels.
        let (count, most) = support::differences_over(&source, &image, 8);
        assert!(
            count * 100 <= 64 * 48,
            "{file}: {count} pixels differ by more than 8 levels (by up to {most})"
        );
    }
}

/// A `.glb`'s JSON and binary chunk.
pub(crate) fn split_glb(bytes: &[u8]) -> (Value, Vec<u8>) {
    let glb = gltf::binary::Glb::from_slice(bytes).unwrap();
    let json = gltf::json::deserialize::from_slice(&glb.json).unwrap();
    (json, glb.bin.unwrap().into_owned())
}

/// A `.glb` of `json` and `bin`.
pub(crate) fn join_glb(json: &Value, bin: &[u8]) -> Vec<u8> {
    let mut text = gltf::json::serialize::to_vec(json).unwrap();
    text.resize(text.len().next_multiple_of(4), b' ');
    let mut bin = bin.to_vec();
    bin.resize(bin.len().next_multiple_of(4), 0);
    let mut out = Vec::new();
    let total = 12 + 8 + text.len() + 8 + bin.len();
    for word in [0x4654_6C67, 2, total as u32, text.len() as u32, 0x4E4F_534A] {
        out.extend_from_slice(&u32::to_le_bytes(word));
    }
    out.extend_from_slice(&text);
    out.extend_from_slice(&u32::to_le_bytes(bin.len() as u32));
    out.extend_from_slice(&u32::to_le_bytes(0x004E_4942));
    out.extend_from_slice(&bin);
    out
}

/// Loads `json` and `bin` as one `.glb`: its error, if any (which must name the
/// file), and never a panic.
fn meshopt_error(json: &Value, bin: &[u8]) -> Option<String> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("broken.glb");
    std::fs::write(&path, join_glb(json, bin)).unwrap();
    let result = std::panic::catch_unwind(|| formats::load(&path).err());
    let error = result.unwrap_or_else(|_| panic!("a panic"))?.to_string();
    assert!(
        error.starts_with(&path.display().to_string()),
        "the error does not name the file: {error}"
    );
    Some(error)
}

#[test]
fn meshopt_fallback_buffers_are_never_read() {
    let (mut json, bin) = split_glb(&std::fs::read(meshopt_fixture("torus-filters.glb")).unwrap());
    let fallback = &mut json["buffers"][1];
    assert_eq!(
        fallback["extensions"]["EXT_meshopt_compression"]["fallback"],
        Value::Bool(true)
    );
    // gltfpack's fallback has no uri; one naming a file that is not there, and
    // claiming a terabyte, is not read either.
    fallback["uri"] = Value::from("missing.bin");
    fallback["byteLength"] = Value::from(1u64 << 40);
    assert_eq!(meshopt_error(&json, &bin), None);
}

#[test]
fn truncated_corrupt_or_impossible_meshopt_streams_are_errors_naming_the_file_and_view() {
    let (json, bin) = split_glb(&std::fs::read(meshopt_fixture("torus-filters.glb")).unwrap());
    let loaded = meshopt_error(&json, &bin);
    assert_eq!(loaded, None, "the fixture itself must load");
    let name = "EXT_meshopt_compression";
    let views: Vec<usize> = (0..json["bufferViews"].as_array().unwrap().len())
        .filter(|&v| !json["bufferViews"][v]["extensions"][name].is_null())
        .collect();
    assert_eq!(
        views.len(),
        4,
        "positions, normals, texture coordinates, indices"
    );
    for &view in &views {
        let extension = &json["bufferViews"][view]["extensions"][name];
        let offset = extension["byteOffset"].as_u64().unwrap() as usize;
        let length = extension["byteLength"].as_u64().unwrap() as usize;
        let named = format!("buffer view {view}: {name}");
        // Cut short, at several lengths.
        for cut in [0, 1, 16, length / 2, length - 1] {
            let mut json = json.clone();
            json["bufferViews"][view]["extensions"][name]["byteLength"] = Value::from(cut);
            let error = meshopt_error(&json, &bin).unwrap_or_default();
            assert!(error.contains(&named), "view {view} cut at {cut}: {error}");
        }
        // Another codec or version: the header byte.
        let mut broken = bin.clone();
        broken[offset] ^= 0x40;
        let error = meshopt_error(&json, &broken).unwrap_or_default();
        assert!(
            error.contains(&format!("{named}: the stream begins with byte")),
            "{error}"
        );
        // Bits flipped anywhere: an error naming the view, or other values (meshopt
        // streams have no checksum), never a panic.
        for at in (1..length).step_by(53) {
            let mut broken = bin.clone();
            broken[offset + at] ^= 0xA5;
            if let Some(error) = meshopt_error(&json, &broken) {
                assert!(error.contains("broken.glb: "), "byte {at}: {error}");
            }
        }
    }
    // More elements than the stream can hold: refused before anything is allocated.
    let mut huge = json.clone();
    huge["bufferViews"][views[0]]["extensions"][name]["count"] = Value::from(1u64 << 40);
    let error = meshopt_error(&huge, &bin).unwrap_or_default();
    assert!(error.contains("cannot come from"), "{error}");
    // A stream in a buffer that does not exist, or in the fallback buffer.
    for (buffer, message) in [(7, "buffer 7 does not exist"), (1, "a fallback buffer")] {
        let mut json = json.clone();
        json["bufferViews"][views[0]]["extensions"][name]["buffer"] = Value::from(buffer);
        let error = meshopt_error(&json, &bin).unwrap_or_default();
        assert!(error.contains(message), "{error}");
    }
    // A stride other than the buffer view's.
    let mut other = json.clone();
    other["bufferViews"][views[0]]["extensions"][name]["byteStride"] = Value::from(16);
    let error = meshopt_error(&other, &bin).unwrap_or_default();
    assert!(
        error.contains("a byteStride of 16, the buffer view's is 12"),
        "{error}"
    );
    // A stride the mode does not allow (the decoder would assert it).
    let mut json = json.clone();
    json["bufferViews"][views[3]]["extensions"][name]["byteStride"] = Value::from(3);
    let error = meshopt_error(&json, &bin).unwrap_or_default();
    assert!(error.contains("not 2 or 4"), "{error}");
}

/// `torus-filters.glb` with `EXT_meshopt_compression` renamed
/// `KHR_meshopt_compression` throughout: the KHR extension reads EXT's streams
/// (vertex codec version 0) as they are, as its specification says.
fn khr_twin(json: &Value) -> Value {
    let text = gltf::json::serialize::to_string(json).unwrap();
    let renamed = text.replace("EXT_meshopt_compression", "KHR_meshopt_compression");
    gltf::json::deserialize::from_str(&renamed).unwrap()
}

#[test]
fn khr_meshopt_files_render_as_their_ext_twins() {
    let (json, bin) = split_glb(&std::fs::read(meshopt_fixture("torus-filters.glb")).unwrap());
    let dir = tempfile::tempdir().unwrap();
    let khr = dir.path().join("khr.glb");
    std::fs::write(&khr, join_glb(&khr_twin(&json), &bin)).unwrap();
    let flags = ["--width", "64", "--height", "48"];
    let ext = support::render(
        &meshopt_fixture("torus-filters.glb"),
        &dir.path().join("e.png"),
        &flags,
    );
    let image = support::render(&khr, &dir.path().join("k.png"), &flags);
    assert_eq!(support::differences(&ext, &image), (0, 0));
    assert!(ext.iter().any(|&b| b > 0));
}

/// A deterministic stream of numbers (xorshift64*), for the corruption loop.
struct Numbers(u64);

impl Numbers {
    fn below(&mut self, n: usize) -> usize {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 33) as usize % n.max(1)
    }
}

/// Fuzz-style, with both extensions: meshopt views with their streams cut, bytes
/// overwritten, and counts, strides and offsets changed at random give an error
/// naming the file, or a description the fuzz targets' checks accept; never a panic,
/// a crash or an allocation beyond what the stream's size allows (the reader
/// refuses counts larger than a stream can hold before allocating).
#[test]
fn corrupted_meshopt_views_of_either_extension_are_errors_or_sound_descriptions() {
    let (ext, bin) = split_glb(&std::fs::read(meshopt_fixture("torus-filters.glb")).unwrap());
    let dir = tempfile::tempdir().unwrap();
    let mut numbers = Numbers(0x9e37_79b9_7f4a_7c15);
    let (mut errors, mut loaded) = (0, 0);
    for (json, name) in [
        (ext.clone(), "EXT_meshopt_compression"),
        (khr_twin(&ext), "KHR_meshopt_compression"),
    ] {
        let views: Vec<usize> = (0..json["bufferViews"].as_array().unwrap().len())
            .filter(|&v| !json["bufferViews"][v]["extensions"][name].is_null())
            .collect();
        for _ in 0..150 {
            let (mut json, mut bin) = (json.clone(), bin.clone());
            let view = views[numbers.below(views.len())];
            let extension = &mut json["bufferViews"][view]["extensions"][name];
            let offset = extension["byteOffset"].as_u64().unwrap() as usize;
            let length = extension["byteLength"].as_u64().unwrap() as usize;
            let count = extension["count"].as_u64().unwrap() as usize;
            match numbers.below(5) {
                0 => extension["byteLength"] = Value::from(numbers.below(length + 8)),
                1 => extension["count"] = Value::from(numbers.below(4 * count + 2)),
                2 => {
                    let strides = [0, 1, 2, 3, 4, 6, 8, 12, 16, 256, 260];
                    extension["byteStride"] = Value::from(strides[numbers.below(strides.len())]);
                }
                3 => extension["byteOffset"] = Value::from(numbers.below(bin.len() + 8)),
                _ => {
                    for _ in 0..1 + numbers.below(8) {
                        let at = offset + numbers.below(length);
                        bin[at] = numbers.below(256) as u8;
                    }
                }
            }
            let glb = join_glb(&json, &bin);
            match std::panic::catch_unwind(|| formats::parse_gltf(&glb, Path::new("c.glb"))) {
                Err(_) => panic!("a panic"),
                Ok(Err(_)) => errors += 1,
                Ok(Ok(_)) => loaded += 1,
            }
            // The fuzz targets' own checks: an error names the file, a description
            // holds no index out of range and no non-finite value in use.
            crate::fuzz_checks::check_gltf(&glb, dir.path());
        }
    }
    // Both outcomes occur: the loop reaches the decoders, not only the checks.
    assert!(errors > 0 && loaded > 0, "{errors} errors, {loaded} loaded");
}
