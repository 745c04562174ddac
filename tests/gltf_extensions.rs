//! glTF extensions and texture features beyond the core material: `KHR_materials_unlit`,
//! `EXT_texture_webp`, extensions read and ignored (`KHR_materials_variants`,
//! `KHR_xmp_json_ld`), and textures on texture coordinates other than `TEXCOORD_0`.
//! Each test writes a small glTF file of its own: a square facing +z.

use std::path::{Path, PathBuf};

use serde_json::{Value, json};

use crate::support;

/// A vertex attribute of the square: its name, glTF type and values, 4 vertices.
struct Attribute {
    name: &'static str,
    kind: &'static str,
    values: Vec<f32>,
}

fn attribute(name: &'static str, kind: &'static str, values: &[f32]) -> Attribute {
    Attribute {
        name,
        kind,
        values: values.to_vec(),
    }
}

/// The square's corners (-1..1 in x and y, z = 0), normals +z, `TEXCOORD_0` from 0
/// to 1.
fn square_attributes() -> Vec<Attribute> {
    vec![
        attribute(
            "POSITION",
            "VEC3",
            &[-1., -1., 0., 1., -1., 0., 1., 1., 0., -1., 1., 0.],
        ),
        attribute(
            "NORMAL",
            "VEC3",
            &[0., 0., 1., 0., 0., 1., 0., 0., 1., 0., 0., 1.],
        ),
        attribute("TEXCOORD_0", "VEC2", &[0., 1., 1., 1., 1., 0., 0., 0.]),
    ]
}

/// Writes `name.gltf` (with `name.bin`) into `dir`: the square with `attributes`,
/// material `material` and whatever top-level keys `extra` adds (textures, images,
/// extensions, lights, further nodes).
fn write_square(
    dir: &Path,
    name: &str,
    attributes: &[Attribute],
    material: Value,
    extra: Value,
) -> PathBuf {
    let mut bin: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut accessors = Vec::new();
    let mut attrs = serde_json::Map::new();
    for (i, a) in attributes.iter().enumerate() {
        let offset = bin.len();
        for v in &a.values {
            bin.extend(v.to_le_bytes());
        }
        views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": a.values.len() * 4}));
        let mut accessor =
            json!({"bufferView": i, "componentType": 5126, "count": 4, "type": a.kind});
        if a.name == "POSITION" {
            accessor["min"] = json!([-1, -1, 0]);
            accessor["max"] = json!([1, 1, 0]);
        }
        accessors.push(accessor);
        attrs.insert(a.name.into(), json!(i));
    }
    let offset = bin.len();
    for i in [0u16, 1, 2, 0, 2, 3] {
        bin.extend(i.to_le_bytes());
    }
    views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": 12}));
    accessors.push(
        json!({"bufferView": views.len() - 1, "componentType": 5123, "count": 6, "type": "SCALAR"}),
    );
    std::fs::write(dir.join(format!("{name}.bin")), &bin).unwrap();
    let mut gltf = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": attrs, "indices": accessors.len() - 1, "material": 0}]}],
        "materials": [material],
        "buffers": [{"uri": format!("{name}.bin"), "byteLength": bin.len()}],
        "bufferViews": views,
        "accessors": accessors,
    });
    if let (Value::Object(gltf), Value::Object(extra)) = (&mut gltf, extra) {
        for (key, value) in extra {
            match (gltf.get_mut(&key), value) {
                (Some(Value::Array(list)), Value::Array(more)) => list.extend(more),
                (_, value) => {
                    gltf.insert(key, value);
                }
            }
        }
    }
    let path = dir.join(format!("{name}.gltf"));
    std::fs::write(&path, serde_json::to_string_pretty(&gltf).unwrap()).unwrap();
    path
}

/// The linear RGB of pixel (`x`, `y`) of EXR file `path`.
fn exr_pixel(path: &Path, x: usize, y: usize) -> [f32; 3] {
    let (width, _, channels) = support::read_exr(path);
    ["R", "G", "B"].map(|c| channels[c][y * width + x])
}

/// Renders `scene` with `flags` (with `-q`), asserting success; returns stderr.
fn render(scene: &Path, out: &Path, flags: &[&str]) -> String {
    let mut args = vec![
        "render",
        scene.to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ];
    args.extend(flags);
    let output = support::raytracer(&args);
    let stderr = support::stderr(&output);
    assert!(output.status.success(), "{stderr}");
    stderr
}

fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// An unlit square: base colour factor times a 1x1 texture times a vertex colour,
/// constant over the square, under a bright point light and a camera looking at it
/// head on; the expected linear colour.
fn unlit_square(dir: &Path, unlit: bool) -> (PathBuf, [f32; 3]) {
    let texel = [200u8, 120, 40];
    support::write_png(&dir.join("texel.png"), 1, 1, 3, &texel);
    let factor = [0.9f32, 0.7, 0.5];
    let vertex = [0.5f32, 1.0, 0.8];
    let mut attributes = square_attributes();
    attributes.push(attribute("COLOR_0", "VEC3", &vertex.repeat(4)));
    let mut material = json!({
        "pbrMetallicRoughness": {
            "baseColorFactor": [factor[0], factor[1], factor[2], 1.0],
            "baseColorTexture": {"index": 0},
            "metallicFactor": 0.0,
        },
        "emissiveFactor": [1.0, 0.0, 0.0],
    });
    if unlit {
        material["extensions"] = json!({"KHR_materials_unlit": {}});
    }
    let path = write_square(
        dir,
        if unlit { "unlit" } else { "lit" },
        &attributes,
        material,
        json!({
            "extensionsUsed": ["KHR_materials_unlit", "KHR_lights_punctual"],
            "textures": [{"source": 0}],
            "images": [{"uri": "texel.png"}],
            "extensions": {"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 50.0}]}},
            "nodes": [
                {"camera": 0, "translation": [0, 0, 3]},
                {"extensions": {"KHR_lights_punctual": {"light": 0}}, "translation": [0.5, 0.5, 1]},
            ],
            "cameras": [{"type": "perspective", "perspective": {"yfov": 0.5, "znear": 0.01}}],
            "scenes": [{"nodes": [0, 1, 2]}],
        }),
    );
    let want =
        std::array::from_fn(|i| factor[i] * srgb_to_linear(texel[i] as f32 / 255.0) * vertex[i]);
    (path, want)
}

/// Renders the unlit square in `mode` to EXR (the linear film, before the tone map)
/// and checks that three pixels are its base colour.
fn check_unlit(mode: &str) {
    let dir = tempfile::tempdir().unwrap();
    let (path, want) = unlit_square(dir.path(), true);
    let out = dir.path().join(format!("{mode}.exr"));
    let stderr = render(
        &path,
        &out,
        &[
            "--mode", mode, "--width", "32", "--height", "32", "--spp", "4",
        ],
    );
    assert!(!stderr.contains("KHR_materials_unlit"), "{stderr}");
    for (x, y) in [(16, 16), (10, 20), (20, 12)] {
        let got = exr_pixel(&out, x, y);
        for c in 0..3 {
            assert!(
                (got[c] - want[c]).abs() < 1e-3,
                "{mode} mode at ({x}, {y}): {got:?}, want {want:?}"
            );
        }
    }
    // The same square lit: not its base colour (the test can tell).
    let (lit, _) = unlit_square(dir.path(), false);
    let out = dir.path().join("lit.exr");
    render(
        &lit,
        &out,
        &[
            "--mode", mode, "--width", "32", "--height", "32", "--spp", "4",
        ],
    );
    let got = exr_pixel(&out, 16, 16);
    assert!((0..3).any(|c| (got[c] - want[c]).abs() > 0.05), "{got:?}");
}

#[test]
fn an_unlit_surface_shows_its_base_colour_exactly_in_path_mode() {
    check_unlit("path");
}

#[test]
fn an_unlit_surface_shows_its_base_colour_exactly_in_full_mode() {
    check_unlit("full");
}

fn webp_fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/gltf/webp")
        .join(name)
}

/// A square whose base colour texture is texture 0, with `texture` its JSON and
/// `images` the file's images (copied from the WebP fixture's folder by name).
fn textured_square(
    dir: &Path,
    name: &str,
    texture: Value,
    images: &[&str],
    used: Value,
) -> PathBuf {
    for image in images {
        let from = webp_fixture(image);
        if from.exists() {
            std::fs::copy(from, dir.join(image)).unwrap();
        }
    }
    let images: Vec<Value> = images.iter().map(|i| json!({"uri": i})).collect();
    let mut extra = json!({"textures": [texture], "images": images});
    if let (Value::Object(extra), Value::Object(used)) = (&mut extra, used) {
        extra.extend(used);
    }
    write_square(
        dir,
        name,
        &square_attributes(),
        json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}),
        extra,
    )
}

/// The base colour of the first material of `path` at texture coordinates `uv`
/// (nearest texel centres of the 4x3 fixture), and its warnings.
fn base_colours(path: &Path) -> (Vec<raytracer::math::Vec3>, Vec<String>) {
    let loaded = raytracer::formats::load(path).unwrap_or_else(|e| panic!("{e}"));
    let material = &loaded.description.materials[0];
    let mut colours = Vec::new();
    for y in 0..3 {
        for x in 0..4 {
            let uv = raytracer::math::Vec2::new((x as f32 + 0.5) / 4.0, (y as f32 + 0.5) / 3.0);
            colours.push(material.pbr_at(uv).unwrap().base_color);
        }
    }
    (colours, loaded.description.warnings)
}

#[test]
fn a_webp_texture_reads_the_same_texels_as_its_png() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let webp =
        json!({"extensionsUsed": ["EXT_texture_webp"], "extensionsRequired": ["EXT_texture_webp"]});
    let used = json!({"extensionsUsed": ["EXT_texture_webp"]});
    let png = textured_square(d, "png", json!({"source": 0}), &["texels.png"], json!({}));
    let (want, warnings) = base_colours(&png);
    assert!(warnings.is_empty(), "{warnings:?}");
    // The texels differ: a test that can fail.
    assert!(want.windows(2).all(|w| w[0] != w[1]), "{want:?}");
    // Required, with no core source; and with a core fallback (a different image,
    // not read).
    support::write_png(&d.join("grey.png"), 1, 1, 3, &[128, 128, 128]);
    for (name, texture, images) in [
        (
            "required",
            json!({"extensions": {"EXT_texture_webp": {"source": 0}}}),
            vec!["texels.webp"],
        ),
        (
            "fallback",
            json!({"source": 1, "extensions": {"EXT_texture_webp": {"source": 0}}}),
            vec!["texels.webp", "grey.png"],
        ),
    ] {
        let extensions = if name == "required" {
            webp.clone()
        } else {
            used.clone()
        };
        let path = textured_square(d, name, texture, &images, extensions);
        let (got, warnings) = base_colours(&path);
        assert!(warnings.is_empty(), "{name}: {warnings:?}");
        for (g, w) in got.iter().zip(&want) {
            assert!(
                (*g - *w).abs().max_element() < 1e-6,
                "{name}: {got:?} vs {want:?}"
            );
        }
    }
    // A WebP that cannot be decoded: its core image instead, with a warning naming
    // the file and the image; without one, the surface renders without it.
    std::fs::write(d.join("broken.webp"), b"RIFF\x10\x00\x00\x00WEBPVP8L\x00").unwrap();
    std::fs::copy(webp_fixture("texels.png"), d.join("texels.png")).unwrap();
    let path = textured_square(
        d,
        "broken",
        json!({"source": 1, "extensions": {"EXT_texture_webp": {"source": 0}}}),
        &["broken.webp", "texels.png"],
        used.clone(),
    );
    let (got, warnings) = base_colours(&path);
    assert_eq!(got, want);
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(
        warnings[0].starts_with(&format!("{}: image 0: ", path.display()))
            && warnings[0].contains("core image"),
        "{warnings:?}"
    );
    let path = textured_square(
        d,
        "broken-required",
        json!({"extensions": {"EXT_texture_webp": {"source": 0}}}),
        &["broken.webp"],
        webp.clone(),
    );
    let loaded = raytracer::formats::load(&path).unwrap();
    let warnings = &loaded.description.warnings;
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(
        warnings[0].starts_with(&format!("{}: image 0: cannot", path.display()))
            && warnings[0].ends_with("the surface renders without it"),
        "{warnings:?}"
    );
    assert!(loaded.description.materials[0].maps.is_none());
    // An extension whose source is no image of the file: its core source, with a
    // warning; with none, an error naming the file.
    let path = textured_square(
        d,
        "bad-source",
        json!({"source": 0, "extensions": {"EXT_texture_webp": {"source": 7}}}),
        &["texels.png"],
        used,
    );
    let (got, warnings) = base_colours(&path);
    assert_eq!(got, want);
    assert_eq!(
        warnings,
        [format!(
            "{}: texture 0: its EXT_texture_webp 'source' is not an image of the file; its core source is read",
            path.display()
        )]
    );
    let path = textured_square(
        d,
        "no-source",
        json!({"extensions": {"EXT_texture_webp": {"source": 7}}}),
        &["texels.png"],
        webp,
    );
    let error = raytracer::formats::load(&path).unwrap_err().to_string();
    assert!(error.starts_with(&path.display().to_string()), "{error}");
}

/// The base colour of the first material of `path` at the centres of the four 4x4
/// blocks of an 8x8 texture (each block one colour), and its warnings.
fn block_colours(path: &Path) -> (Vec<raytracer::math::Vec3>, Vec<String>) {
    let loaded = raytracer::formats::load(path).unwrap_or_else(|e| panic!("{e}"));
    let material = &loaded.description.materials[0];
    let colours = [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)].map(|(u, v)| {
        material
            .pbr_at(raytracer::math::Vec2::new(u, v))
            .unwrap()
            .base_color
    });
    (colours.to_vec(), loaded.description.warnings)
}

/// `KHR_texture_basisu`: `tests/data/gltf/ktx2/blocks.png` (8x8, four blocks of four
/// colours) encoded as KTX2 by the reference encoder (`basisu` 1.16.4: UASTC with
/// zstd supercompression, and ETC1S), read through the extension's source: the PNG's
/// colours within each codec's error, required with no core source or preferred to a
/// core fallback (a grey image, not read); a KTX2 that cannot be decoded falls back
/// to the core image with a warning naming the file and image, or without one leaves
/// the surface untextured, as any unreadable image.
#[test]
fn a_ktx2_texture_reads_the_texels_of_its_png_within_the_codecs_error() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/gltf/ktx2");
    for file in ["blocks.png", "blocks-uastc.ktx2", "blocks-etc1s.ktx2"] {
        std::fs::copy(fixtures.join(file), d.join(file)).unwrap();
    }
    let png = textured_square(d, "png", json!({"source": 0}), &["blocks.png"], json!({}));
    let (want, _) = block_colours(&png);
    assert!(want.windows(2).all(|w| w[0] != w[1]), "{want:?}");
    let required = json!({"extensionsUsed": ["KHR_texture_basisu"], "extensionsRequired": ["KHR_texture_basisu"]});
    let used = json!({"extensionsUsed": ["KHR_texture_basisu"]});
    support::write_png(&d.join("grey.png"), 1, 1, 3, &[128, 128, 128]);
    for (file, tolerance) in [("blocks-uastc.ktx2", 0.01), ("blocks-etc1s.ktx2", 0.03)] {
        for (name, texture, images, extensions) in [
            (
                "required",
                json!({"extensions": {"KHR_texture_basisu": {"source": 0}}}),
                vec![file],
                required.clone(),
            ),
            (
                "fallback",
                json!({"source": 1, "extensions": {"KHR_texture_basisu": {"source": 0}}}),
                vec![file, "grey.png"],
                used.clone(),
            ),
        ] {
            let path = textured_square(d, &format!("{name}-{file}"), texture, &images, extensions);
            let (got, warnings) = block_colours(&path);
            assert!(warnings.is_empty(), "{file}, {name}: {warnings:?}");
            let error = (got.iter().zip(&want))
                .map(|(g, w)| (*g - *w).abs().max_element())
                .fold(0.0f32, f32::max);
            eprintln!("{file}, {name}: largest error {error}");
            assert!(error < tolerance, "{file}, {name}: {got:?} vs {want:?}");
        }
    }
    // Not a Basis Universal KTX2 (its identifier, then zeros): the core image, with
    // a warning; without one, the surface untextured.
    let mut broken = vec![
        0xAB, b'K', b'T', b'X', b' ', b'2', b'0', 0xBB, b'\r', b'\n', 0x1A, b'\n',
    ];
    broken.extend([0u8; 60]);
    std::fs::write(d.join("broken.ktx2"), broken).unwrap();
    let path = textured_square(
        d,
        "broken",
        json!({"source": 1, "extensions": {"KHR_texture_basisu": {"source": 0}}}),
        &["broken.ktx2", "blocks.png"],
        used,
    );
    let (got, warnings) = block_colours(&path);
    assert_eq!(got, want);
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(
        warnings[0].starts_with(&format!("{}: image 0: ", path.display()))
            && warnings[0].contains("KTX2")
            && warnings[0].contains("core image"),
        "{warnings:?}"
    );
    let path = textured_square(
        d,
        "broken-required",
        json!({"extensions": {"KHR_texture_basisu": {"source": 0}}}),
        &["broken.ktx2"],
        required,
    );
    let loaded = raytracer::formats::load(&path).unwrap();
    assert_eq!(loaded.description.warnings.len(), 1);
    assert!(loaded.description.materials[0].maps.is_none());
}

#[test]
fn variants_and_xmp_metadata_are_read_without_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let material = |colour: [f32; 3]| json!({"pbrMetallicRoughness": {"baseColorFactor": [colour[0], colour[1], colour[2], 1.0], "metallicFactor": 0.0}});
    let path = write_square(
        dir.path(),
        "variants",
        &square_attributes(),
        material([0.8, 0.1, 0.1]),
        json!({
            "extensionsUsed": ["KHR_materials_variants", "KHR_xmp_json_ld"],
            "materials": [material([0.1, 0.8, 0.1])],
            "extensions": {
                "KHR_materials_variants": {"variants": [{"name": "green"}]},
                "KHR_xmp_json_ld": {"packets": [{"@context": {"dc": "http://purl.org/dc/elements/1.1/"}, "dc:creator": {"@list": ["A. Modeller"]}}]},
            },
            "asset": {"version": "2.0", "extensions": {"KHR_xmp_json_ld": {"packet": 0}}},
        }),
    );
    // The primitive's variant mapping: green under variant 0.
    let mut gltf: Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    gltf["meshes"][0]["primitives"][0]["extensions"] =
        json!({"KHR_materials_variants": {"mappings": [{"material": 1, "variants": [0]}]}});
    std::fs::write(&path, gltf.to_string()).unwrap();
    let loaded = raytracer::formats::load(&path).unwrap();
    let d = &loaded.description;
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    // The default look: the primitive's own material, red.
    let used: Vec<_> = d.triangles.iter().map(|t| t.material).collect();
    assert_eq!(used.len(), 2);
    for m in used {
        let colour = d.materials[m.0 as usize]
            .pbr_at(raytracer::math::Vec2::ZERO)
            .unwrap()
            .base_color;
        assert_eq!(colour, raytracer::math::Vec3::new(0.8, 0.1, 0.1));
    }
}

/// The base colour where a ray down -z at (`x`, `y`) meets the square of `path`.
fn base_colour_at(path: &Path, points: &[(f32, f32)]) -> (Vec<raytracer::math::Vec3>, Vec<String>) {
    use raytracer::math::{Ray, Vec3};
    let loaded = raytracer::formats::load(path).unwrap_or_else(|e| panic!("{e}"));
    let warnings = loaded.description.warnings.clone();
    let scene = raytracer::Scene::build(loaded.description, &raytracer::BvhParams::default());
    let colours = points
        .iter()
        .map(|&(x, y)| {
            let hit = scene
                .intersect(&Ray::new(Vec3::new(x, y, 1.0), -Vec3::Z))
                .expect("the ray meets the square");
            let material = &scene.materials[hit.material.0 as usize];
            material
                .pbr_at_point(hit.uv, hit.colour)
                .unwrap()
                .base_color
        })
        .collect();
    (colours, warnings)
}

#[test]
fn textures_on_another_texture_coordinate_set_read_that_set() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::copy(webp_fixture("texels.png"), d.join("texels.png")).unwrap();
    let points = [
        (-0.8, -0.8),
        (-0.3, 0.6),
        (0.2, -0.1),
        (0.7, 0.8),
        (0.9, -0.5),
    ];
    let extra = || json!({"textures": [{"source": 0}], "images": [{"uri": "texels.png"}]});
    // The reference: the texture on TEXCOORD_0.
    let reference = write_square(
        d,
        "reference",
        &square_attributes(),
        json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}),
        extra(),
    );
    let (want, warnings) = base_colour_at(&reference, &points);
    assert!(warnings.is_empty(), "{warnings:?}");
    // The same coordinates as TEXCOORD_1, with TEXCOORD_0 all at one corner.
    let mut attributes = square_attributes();
    attributes[2].values = vec![0.9; 8];
    attributes.push(attribute(
        "TEXCOORD_1",
        "VEC2",
        &[0., 1., 1., 1., 1., 0., 0., 0.],
    ));
    let on_one =
        |name: &str, material: Value| write_square(d, name, &attributes, material, extra());
    let path = on_one(
        "set1",
        json!({
            "pbrMetallicRoughness": {"baseColorTexture": {"index": 0, "texCoord": 1}, "metallicRoughnessTexture": {"index": 0, "texCoord": 1}},
            // Not read, so its set does not count.
            "occlusionTexture": {"index": 0, "texCoord": 0},
        }),
    );
    let (got, warnings) = base_colour_at(&path, &points);
    assert!(warnings.is_empty(), "{warnings:?}");
    assert_eq!(got, want);
    // A texture transform's texCoord overrides the texture's own.
    let path = write_square(
        d,
        "transform",
        &attributes,
        json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0, "texCoord": 0, "extensions": {"KHR_texture_transform": {"texCoord": 1}}}}}),
        json!({"textures": [{"source": 0}], "images": [{"uri": "texels.png"}], "extensionsUsed": ["KHR_texture_transform"]}),
    );
    let (got, warnings) = base_colour_at(&path, &points);
    assert!(warnings.is_empty(), "{warnings:?}");
    assert_eq!(got, want);
    // Mixed sets: the base colour's, with one warning naming the file.
    let path = on_one(
        "mixed",
        json!({
            "pbrMetallicRoughness": {"baseColorTexture": {"index": 0, "texCoord": 1}},
            "emissiveTexture": {"index": 0},
        }),
    );
    let (got, warnings) = base_colour_at(&path, &points);
    assert_eq!(got, want);
    assert_eq!(
        warnings,
        [format!(
            "{}: material 0: its textures use TEXCOORD_0 and TEXCOORD_1, but one set is read per primitive: TEXCOORD_1, for all of them",
            path.display()
        )]
    );
    // A set the primitive does not have: TEXCOORD_0, with a warning.
    let path = on_one(
        "missing",
        json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0, "texCoord": 2}}}),
    );
    let (got, warnings) = base_colour_at(&path, &points);
    assert!(
        got.windows(2)
            .all(|w| (w[0] - w[1]).abs().max_element() < 1e-5),
        "{got:?}"
    );
    assert_eq!(
        warnings,
        [format!(
            "{}: mesh 0 primitive 0: its material's textures use TEXCOORD_2, which it does not have; TEXCOORD_0 is read instead",
            path.display()
        )]
    );
}
