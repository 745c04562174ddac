//! glTF's compressed geometry: `KHR_draco_mesh_compression`, checked against the
//! uncompressed model (`tests/data/gltf/draco/expected.json`, written by its
//! `make_expected.py` from the uncompressed 2CylinderEngine), and corrupt Draco data.

use std::path::{Path, PathBuf};

use gltf::json::Value;
use raytracer::formats;
use raytracer::math::Vec3;

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
