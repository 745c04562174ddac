//! glTF 2.0 scenes: the fixtures of `tests/data/gltf/` (written by its
//! `make_fixtures.py`) as separate files, data URIs and GLB; node transforms, the
//! material mapping, textures, the alpha mask, emission, the camera, lights; and
//! malformed files.

use std::path::{Path, PathBuf};
use std::process::Command;

use raytracer::formats::{self, LoadedScene, SceneFormat};
use raytracer::material::BlendRule;
use raytracer::math::{Float, Ray, Vec2, Vec3};
use raytracer::options::Origin;
use raytracer::{BvhParams, Scene};

use crate::support;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/gltf")
        .join(name)
}

fn close(a: Vec3, b: Vec3) -> bool {
    (a - b).abs().max_element() < 1e-5
}

/// The three spellings of the fixture scene.
fn all_fixtures() -> Vec<(PathBuf, LoadedScene)> {
    ["scene.gltf", "scene.glb", "datauri.gltf"]
        .into_iter()
        .map(|name| {
            let path = fixture(name);
            let mut loaded = formats::load(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
            // Its quad hangs from several nodes: stored once, placed by instances;
            // these tests read the copies where they are placed.
            let d = &mut loaded.description;
            d.flatten_instances().unwrap();
            // Flattened copies come after the meshes used once: put the quad's two
            // (nodes 1 and 2, four triangles) back first, in node order, as these
            // tests number them.
            d.triangles.rotate_right(4);
            for indices in [&mut d.triangle_normals, &mut d.triangle_texcoords] {
                if !indices.is_empty() {
                    indices.rotate_right(4);
                }
            }
            (path, loaded)
        })
        .collect()
}

#[test]
fn gltf_and_glb_are_scene_formats() {
    assert_eq!(SceneFormat::of(Path::new("a.glb")), Some(SceneFormat::Gltf));
    assert_eq!(
        SceneFormat::of(Path::new("A.GLTF")),
        Some(SceneFormat::Gltf)
    );
    assert!(formats::SUPPORTED_EXTENSIONS.contains(".glb"));
}

#[test]
fn meshes_sit_under_their_node_transforms() {
    for (path, loaded) in all_fixtures() {
        let d = &loaded.description;
        assert!(
            d.warnings.is_empty(),
            "{}: {:?}",
            path.display(),
            d.warnings
        );
        // Five quads of two triangles.
        assert_eq!(d.triangles.len(), 10, "{}", path.display());
        let corners = |t: usize| d.triangles[t].positions.map(|i| d.positions[i as usize]);
        // The quad: scaled by 2, moved by +x, then its group moved to z = -5.
        let [a, b, c] = corners(0);
        assert!(close(a, Vec3::new(-1.0, -2.0, -5.0)), "{a}");
        assert!(close(b, Vec3::new(3.0, -2.0, -5.0)), "{b}");
        assert!(close(c, Vec3::new(3.0, 2.0, -5.0)), "{c}");
        // The mirrored copy still faces +z: its winding was turned back.
        let [a, b, c] = corners(2);
        let normal = (b - a).cross(c - a);
        assert!(normal.z > 0.0, "{}: {normal}", path.display());
        // Normals stay unit +z (the scene normalizes them) and texture coordinates
        // have v turned up: glTF's (0, 0), the top left of the image, is v = 1.
        let n = d.normals_of(0).unwrap().map(|i| d.normals[i as usize]);
        assert!(n.iter().all(|n| n.normalize() == Vec3::Z));
        let uv = d.texcoords_of(0).unwrap().map(|i| d.texcoords[i as usize]);
        assert_eq!(
            uv,
            [
                Vec2::new(0.0, 0.0),
                Vec2::new(1.0, 0.0),
                Vec2::new(1.0, 1.0)
            ]
        );
    }
}

#[test]
fn the_first_camera_sets_the_view_and_flags_can_override_it() {
    for (path, loaded) in all_fixtures() {
        let o = &loaded.options;
        let from = o.look_from.as_ref().unwrap();
        assert!(
            close(from.value, Vec3::new(5.0, 0.0, 0.0)),
            "{}",
            from.value
        );
        // Turned 45 degrees about +y, the camera looks towards (0, 0, -5).
        let to = o.look_to.as_ref().unwrap().value;
        let half = std::f32::consts::FRAC_1_SQRT_2;
        assert!(close(to - from.value, Vec3::new(-half, 0.0, -half)), "{to}");
        assert!(close(o.up.as_ref().unwrap().value, Vec3::Y));
        let fov = o.fov_degrees.as_ref().unwrap();
        assert!((fov.value - 0.8f32.to_degrees()).abs() < 1e-4);
        assert_eq!(
            fov.origin,
            Origin::File {
                path: path.clone(),
                line: 0,
                key: "camera.yfov"
            }
        );
        assert_eq!(
            fov.origin.to_string(),
            format!("{}: camera.yfov", path.display())
        );
        // The aspect ratio 1.5 at the default height.
        assert_eq!(o.width.as_ref().unwrap().value, 720);
        assert_eq!(o.height.as_ref().unwrap().value, 480);
    }
}

#[test]
fn point_lights_come_from_khr_lights_punctual() {
    for (_, loaded) in all_fixtures() {
        let lights = &loaded.description.lights;
        assert_eq!(lights.len(), 1);
        assert!(
            close(lights[0].position, Vec3::new(1.0, 2.0, 4.0)),
            "{}",
            lights[0].position
        );
        assert!(close(lights[0].intensity, Vec3::new(10.0, 5.0, 2.5)));
    }
}

#[test]
fn materials_map_base_colour_metal_roughness_emission_and_the_alpha_mask() {
    for (path, loaded) in all_fixtures() {
        let m = &loaded.description.materials;
        let name = path.display();
        assert_eq!(m.len(), 4, "{name}");
        let (checker, lamp, ghost, metal) = (&m[0], &m[1], &m[2], &m[3]);
        assert_eq!(checker.name, "checker");
        // Dielectric: Kd is the base colour, Ks 4 percent; roughness 1 spreads the
        // highlight as far as a Phong lobe goes (Ns 1, a cosine: Walter's 0 would be
        // flat).
        assert_eq!(checker.diffuse, Vec3::new(1.0, 0.5, 0.25));
        assert!(close(checker.specular, Vec3::splat(0.04)));
        assert_eq!(checker.shininess, 1.0);
        assert_eq!(checker.ambient, Vec3::ZERO);
        // The base colour texture multiplies Kd: red in the top left (glTF uv 0, 0).
        let top_left = checker.at(Vec2::new(0.25, 0.75)).diffuse;
        assert!(
            close(top_left, Vec3::new(1.0, 0.0, 0.0)),
            "{name}: {top_left}"
        );
        let bottom_right = checker.at(Vec2::new(0.75, 0.25)).diffuse;
        assert!(
            close(bottom_right, Vec3::new(1.0, 0.5, 0.25)),
            "{name}: {bottom_right}"
        );
        // Emission times KHR_materials_emissive_strength.
        assert_eq!(lamp.emission, Vec3::new(4.0, 2.0, 0.0));
        // The mask: base colour alpha 0.3 is below the cutoff 0.5 everywhere.
        let cutout = ghost.cutout().unwrap();
        assert_eq!((cutout.factor, cutout.cutoff), (0.3, 0.5));
        assert!(!cutout.blend);
        assert!(!cutout.keeps(Vec2::new(0.5, 0.5), BlendRule::Stochastic(0), 0));
        // Metal: roughness 0.5 is alpha 0.25, Ns = 2 / alpha^2 - 2 = 30; the base
        // colour is split between the highlight (1 - alpha) and the diffuse (alpha).
        let base = Vec3::new(0.9, 0.6, 0.3);
        assert!(
            close(metal.diffuse, base * 0.25),
            "{name}: {}",
            metal.diffuse
        );
        assert!(
            close(metal.specular, base * 0.75),
            "{name}: {}",
            metal.specular
        );
        assert!((metal.shininess - 30.0).abs() < 1e-3);
    }
}

#[test]
fn the_scene_renders_textures_and_cuts_out_the_masked_quad() {
    let loaded = formats::load(&fixture("scene.glb")).unwrap();
    let scene = Scene::build(loaded.description, &BvhParams::default());
    let down = |x: Float, y: Float| Ray::new(Vec3::new(x, y, 0.0), Vec3::NEG_Z);
    // The textured quad spans x -1..3, y -2..2 at z = -5: its top left is red.
    let hit = scene.intersect(&down(0.0, 1.0)).unwrap();
    assert_eq!(hit.t, 5.0);
    let material = &scene.materials[hit.material.0 as usize];
    assert!(
        close(material.at(hit.uv).diffuse, Vec3::X),
        "{}",
        material.at(hit.uv).diffuse
    );
    // The masked quad at y = -3 is cut out: the ray goes on to the mirrored quad?
    // No: that one spans y -1..1 only; the ray meets nothing.
    assert!(scene.intersect(&down(0.0, -3.5)).is_none());
    // The emitter at y = 3 is there.
    assert_eq!(scene.intersect(&down(0.0, 3.5)).unwrap().t, 5.0);
}

#[test]
fn raytracer_renders_a_glb_with_its_camera_and_a_mesh_file_may_be_gltf() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.png");
    let output = Command::new(env!("CARGO_BIN_EXE_raytracer"))
        .args(["render", fixture("scene.glb").to_str().unwrap(), "-o"])
        .arg(&out)
        .args(["--width", "90"])
        .output()
        .unwrap();
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    // The camera's aspect ratio 1.5, kept for the width given.
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&out).unwrap()));
    let info = decoder.read_info().unwrap();
    assert_eq!((info.info().width, info.info().height), (90, 60));

    // A TOML scene file names the glTF file as a mesh, moved and with its own camera.
    let toml = dir.path().join("scene.toml");
    std::fs::write(
        &toml,
        format!(
            "[camera]\nlook_from = [0, 0, 10]\nlook_to = [0, 0, 0]\n\n[[mesh]]\nfile = {:?}\ntransform.translate = [0, 0, 1]\n",
            fixture("scene.gltf").to_str().unwrap()
        ),
    )
    .unwrap();
    let loaded = formats::load(&toml).unwrap();
    let d = &loaded.description;
    assert_eq!(d.triangles.len(), 10);
    assert_eq!(d.materials.len(), 4);
    assert_eq!(d.lights.len(), 1);
    // The quad's first copy: its two are placed after the meshes used once.
    let first = d.positions[d.triangles[d.triangles.len() - 4].positions[0] as usize];
    assert!(close(first, Vec3::new(-1.0, -2.0, -4.0)), "{first}");
}

/// The error of loading `bytes` as `name` in a fresh folder.
fn error_of(name: &str, bytes: &[u8]) -> String {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, bytes).unwrap();
    let error = formats::load(&path).unwrap_err().to_string();
    assert!(
        error.starts_with(&path.display().to_string()),
        "{name}: the error does not name the file: {error}"
    );
    error
}

#[test]
fn malformed_and_truncated_files_are_errors_naming_the_file() {
    let glb = std::fs::read(fixture("scene.glb")).unwrap();
    // Every truncation of the GLB is an error, never a panic.
    for cut in (0..glb.len()).step_by(97).chain([glb.len() - 1, 12, 20]) {
        let error = error_of("cut.glb", &glb[..cut]);
        assert!(!error.is_empty());
    }
    let error = error_of("bad.gltf", b"{ not json");
    assert!(error.contains("not a valid glTF file"), "{error}");
    // A default scene that does not exist (Assimp's NoScene.gltf), and indices out of
    // range, in words (the crate wrote `invalid glTF: scene: Index out of bounds;`).
    let error = error_of(
        "noscene.gltf",
        br#"{"asset": {"version": "2.0"}, "scene": 0}"#,
    );
    assert!(
        error.ends_with(
            "noscene.gltf: not a valid glTF file: scene: no such scene (the file has 0 scenes)"
        ),
        "{error}"
    );
    let error = error_of(
        "nomesh.gltf",
        br#"{"asset": {"version": "2.0"}, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 4}, {"camera": 1}]}"#,
    );
    assert!(
        error.ends_with(
            "nomesh.gltf: not a valid glTF file: nodes[0].mesh: index out of range; nodes[1].camera: index out of range"
        ),
        "{error}"
    );
    // A missing .bin file.
    let gltf = std::fs::read_to_string(fixture("scene.gltf")).unwrap();
    let error = error_of("lonely.gltf", gltf.as_bytes());
    assert!(
        error.contains("buffer 0 ('scene.bin'): cannot read scene.bin"),
        "{error}"
    );
    // A buffer shorter than the file says.
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("scene.bin"), [0u8; 10]).unwrap();
    std::fs::write(dir.path().join("short.gltf"), &gltf).unwrap();
    let error = formats::load(&dir.path().join("short.gltf"))
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("buffer 0 has 10 bytes, the file says 140"),
        "{error}"
    );
    // An index past the vertices.
    let bin = std::fs::read(fixture("scene.bin")).unwrap();
    let mut bad = bin.clone();
    let at = bad.len() - 12;
    bad[at..at + 2].copy_from_slice(&9u16.to_le_bytes());
    std::fs::write(dir.path().join("scene.bin"), &bad).unwrap();
    std::fs::write(dir.path().join("index.gltf"), &gltf).unwrap();
    let error = formats::load(&dir.path().join("index.gltf"))
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("mesh 0 primitive 0: index 9 out of range (4 vertices)"),
        "{error}"
    );
}

#[test]
fn a_gltf_1_file_is_an_error_that_says_so_and_how_to_convert_it() {
    // glTF 1.0 keeps its objects in maps, not arrays; its version is a string or a
    // number, and a 1.0 GLB says version 1 in its header.
    let json = r#"{"accessors": {"a": {"count": 3}}, "asset": {"version": "1.0"}}"#;
    let numbered = r#"{"meshes": {}, "asset": {"version": 1}}"#;
    let mut glb = b"glTF".to_vec();
    glb.extend_from_slice(&1u32.to_le_bytes());
    glb.extend_from_slice(&[0; 12]);
    for (name, bytes) in [
        ("old.gltf", json.as_bytes()),
        ("number.gltf", numbered.as_bytes()),
        ("old.glb", &glb[..]),
    ] {
        let error = error_of(name, bytes);
        assert!(
            error.contains("a glTF 1.0 file") && error.contains("gltf-pipeline"),
            "{name}: {error}"
        );
    }
    // A broken 2.0 file is not called 1.0.
    let error = error_of(
        "broken.gltf",
        br#"{"asset": {"version": "2.0"}, "meshes": 3}"#,
    );
    assert!(!error.contains("1.0"), "{error}");
}

#[test]
fn position_accessors_without_bounds_are_read_with_one_warning() {
    // The glTF spec requires POSITION's min and max; exporters that leave them out
    // are read anyway, as three.js and Blender read them. Two quads, both unbounded.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("unbounded.gltf");
    let quad = r#"{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3"}"#;
    let text = format!(
        r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0, 1]}}],
        "nodes": [{{"mesh": 0}}, {{"mesh": 1, "translation": [3, 0, 0]}}],
        "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1}}]}},
                   {{"primitives": [{{"attributes": {{"POSITION": 2}}, "indices": 1}}]}}],
        "accessors": [{quad}, {{"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}}, {quad}],
        "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 48}}, {{"buffer": 0, "byteOffset": 48, "byteLength": 12}}],
        "buffers": [{{"byteLength": 62, "uri": "data:application/octet-stream;base64,AACAvwAAAL8AAAAAAACAPwAAAL8AAAAAAACAPwAAAD8AAAAAAACAvwAAAD8AAAAAAAABAAIAAAACAAMAAAA="}}]}}"#
    );
    std::fs::write(&path, text).unwrap();
    let loaded = formats::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let d = &loaded.description;
    let bounds: Vec<&String> = d
        .warnings
        .iter()
        .filter(|w| w.contains("POSITION accessor"))
        .collect();
    assert_eq!(bounds.len(), 1, "{:?}", d.warnings);
    assert!(
        bounds[0].contains("2 POSITION accessor(s)"),
        "{}",
        bounds[0]
    );
    // Both quads, with the positions the buffer holds (not the bounds filled in).
    let scene = Scene::build(loaded.description, &BvhParams::default());
    for x in [0.5, 3.5] {
        let ray = Ray::new(Vec3::new(x, 0.25, 5.0), Vec3::new(0.0, 0.0, -1.0));
        let hit = scene.intersect(&ray).expect("the quad is there");
        assert!((hit.t - 5.0).abs() < 1e-5, "{}", hit.t);
    }
}

#[test]
fn incomplete_triangles_and_points_and_lines_are_one_warning_each() {
    // Assimp's IncorrectVertexArrays/Cube.gltf: triangle lists of 35 vertices (or
    // indices) and primitives of lines. The whole triangles render, as three.js and
    // Assimp read them, with one warning naming the first list and what is skipped;
    // the points and lines, one warning counting them (it named the first alone).
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("incomplete.gltf");
    let quad = r#"{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-1, -0.5, 0], "max": [1, 0.5, 0]}"#;
    let primitive = |mode: u32, indices: bool| {
        format!(
            r#"{{"primitives": [{{"attributes": {{"POSITION": 0}}, "mode": {mode}{}}}]}}"#,
            if indices { r#", "indices": 1"# } else { "" }
        )
    };
    let meshes = [
        primitive(4, true),
        primitive(1, false),
        primitive(0, false),
        primitive(3, true),
        primitive(4, false),
    ]
    .join(", ");
    let text = format!(
        r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0, 1, 2, 3, 4]}}],
        "nodes": [{{"mesh": 0}}, {{"mesh": 1}}, {{"mesh": 2}}, {{"mesh": 3}}, {{"mesh": 4, "translation": [3, 0, 0]}}],
        "meshes": [{meshes}],
        "accessors": [{quad}, {{"bufferView": 1, "componentType": 5123, "count": 5, "type": "SCALAR"}}],
        "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 48}}, {{"buffer": 0, "byteOffset": 48, "byteLength": 12}}],
        "buffers": [{{"byteLength": 62, "uri": "data:application/octet-stream;base64,AACAvwAAAL8AAAAAAACAPwAAAL8AAAAAAACAPwAAAD8AAAAAAACAvwAAAD8AAAAAAAABAAIAAAACAAMAAAA="}}]}}"#
    );
    std::fs::write(&path, text).unwrap();
    let loaded = formats::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let file = path.display();
    assert_eq!(
        loaded.description.warnings,
        [
            format!(
                "{file}: mesh 0 primitive 0: 5 indices for TRIANGLES, not a multiple of 3; the last two are skipped"
            ),
            format!(
                "{file}: mesh 1 primitive 0 and 2 more: points and lines are not rendered; skipped"
            ),
        ]
    );
    // One triangle of each list: (0, 1, 2) of the indices, the first three vertices.
    assert_eq!(loaded.description.triangles.len(), 2);
}

#[test]
fn a_missing_image_is_a_warning_and_the_surface_renders_without_it() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(fixture("scene.bin"), dir.path().join("scene.bin")).unwrap();
    let gltf = std::fs::read_to_string(fixture("scene.gltf")).unwrap();
    let path = dir.path().join("scene.gltf");
    std::fs::write(&path, gltf).unwrap();
    let loaded = formats::load(&path).unwrap();
    let warnings = &loaded.description.warnings;
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(
        warnings[0].starts_with(&format!(
            "{}: image 0: cannot read texture 'checker.png'",
            path.display()
        )),
        "{warnings:?}"
    );
    let checker = &loaded.description.materials[0];
    assert_eq!(
        checker.at(Vec2::new(0.25, 0.75)).diffuse,
        Vec3::new(1.0, 0.5, 0.25)
    );
}

#[test]
fn base_colour_and_emissive_textures_follow_khr_texture_transform() {
    // The fixture with a transform on the checker's base colour texture, and the
    // checker as the lamp's emissive texture under another one.
    let gltf = std::fs::read_to_string(fixture("scene.gltf")).unwrap();
    let transform = |offset: [Float; 2], rotation: Float, scale: [Float; 2]| {
        format!(
            "\"extensions\": {{\"KHR_texture_transform\": {{\"offset\": [{}, {}], \"rotation\": {rotation}, \"scale\": [{}, {}]}}}}",
            offset[0], offset[1], scale[0], scale[1]
        )
    };
    let base = ([0.25, 0.5], 0.4, [1.5, -0.75]);
    let emissive = ([0.0, 1.0], std::f32::consts::FRAC_PI_2, [0.5, 0.5]);
    let base_texture = "\"baseColorTexture\": {\n     \"index\": 0\n    },";
    assert!(gltf.contains(base_texture));
    let changed = gltf
        .replace(
            base_texture,
            &format!(
                "\"baseColorTexture\": {{\"index\": 0, {}}},",
                transform(base.0, base.1, base.2)
            ),
        )
        .replace(
            "\"emissiveFactor\": [",
            &format!(
                "\"emissiveTexture\": {{\"index\": 0, {}}}, \"emissiveFactor\": [",
                transform(emissive.0, emissive.1, emissive.2)
            ),
        )
        .replace(
            "\"extensionsUsed\": [",
            "\"extensionsUsed\": [\n  \"KHR_texture_transform\",",
        );
    let dir = tempfile::tempdir().unwrap();
    for file in ["scene.bin", "checker.png"] {
        std::fs::copy(fixture(file), dir.path().join(file)).unwrap();
    }
    std::fs::write(dir.path().join("scene.gltf"), changed).unwrap();
    let loaded = formats::load(&dir.path().join("scene.gltf")).unwrap();
    assert!(
        loaded.description.warnings.is_empty(),
        "{:?}",
        loaded.description.warnings
    );
    let plain = &formats::load(&fixture("scene.gltf")).unwrap().description;
    let checker = &plain.materials[0];
    // glTF's mapping in its own coordinates (v down): scale, turn, offset.
    let gltf_transform = |uv: Vec2, (offset, angle, scale): ([Float; 2], Float, [Float; 2])| {
        let g = Vec2::new(uv.x * scale[0], (1.0 - uv.y) * scale[1]);
        let (sin, cos) = angle.sin_cos();
        let g = Vec2::new(
            cos * g.x + sin * g.y + offset[0],
            -sin * g.x + cos * g.y + offset[1],
        );
        Vec2::new(g.x, 1.0 - g.y)
    };
    let materials = &loaded.description.materials;
    let mut differs = false;
    for uv in [
        Vec2::new(0.1, 0.2),
        Vec2::new(0.7, 0.4),
        Vec2::new(0.45, 0.95),
    ] {
        let want = checker.at(gltf_transform(uv, base)).diffuse;
        let got = materials[0].at(uv).diffuse;
        assert!(close(got, want), "base colour at {uv}: {got} vs {want}");
        differs |= !close(got, checker.at(uv).diffuse);
        // The lamp: emissive factor times the checker (texels only: its factor is 1).
        let texel = checker.at(gltf_transform(uv, emissive)).diffuse / Vec3::new(1.0, 0.5, 0.25);
        let want = plain.materials[1].emission * texel;
        let got = materials[1].at(uv).emission;
        assert!(close(got, want), "emission at {uv}: {got} vs {want}");
    }
    assert!(differs, "the transform changed nothing: a weak test");
}

#[test]
fn vertex_colours_multiply_the_base_colour_interpolated_across_each_triangle() {
    let dir = tempfile::tempdir().unwrap();
    for textured in [false, true] {
        let loaded = formats::load(&support::vertex_coloured_gltf(dir.path(), textured)).unwrap();
        assert!(
            loaded.description.warnings.is_empty(),
            "{:?}",
            loaded.description.warnings
        );
        let scene = Scene::build(loaded.description, &BvhParams::default());
        for (x, y) in [
            (0.1, 0.1),
            (0.6, 0.2),
            (0.2, 0.7),
            (0.33, 0.33),
            (0.01, 0.98),
        ] {
            let hit = scene
                .intersect(&Ray::new(Vec3::new(x, y, 1.0), -Vec3::Z))
                .expect("the ray hits the triangle");
            let material = &scene.materials[hit.material.0 as usize];
            // Barycentric weights of (x, y): red at the origin, green along x, blue
            // along y; without a material, times the renderer's grey (Kd 0.8), with
            // the checker texture, times the texture there.
            let weights = Vec3::new(1.0 - x - y, x, y);
            let (want, got) = match textured {
                false => (weights * 0.8, material.at_point(hit.uv, hit.colour).diffuse),
                true => (
                    weights * material.pbr_at(hit.uv).unwrap().base_color,
                    material
                        .pbr_at_point(hit.uv, hit.colour)
                        .unwrap()
                        .base_color,
                ),
            };
            assert!(
                (got - want).abs().max_element() < 1e-4,
                "textured {textured}, at ({x}, {y}): {got} vs {want}"
            );
        }
    }
}

#[test]
fn a_texture_transform_that_overflows_is_a_warning_and_is_ignored() {
    // Offsets and scales near f32's largest value: the converted offset overflows.
    let gltf = std::fs::read_to_string(fixture("scene.gltf")).unwrap();
    let base_texture = "\"baseColorTexture\": {\n     \"index\": 0\n    },";
    let changed = gltf.replace(
        base_texture,
        "\"baseColorTexture\": {\"index\": 0, \"extensions\": {\"KHR_texture_transform\": {\"offset\": [0, -3e38], \"scale\": [1, -3e38]}}},",
    );
    let dir = tempfile::tempdir().unwrap();
    for file in ["scene.bin", "checker.png"] {
        std::fs::copy(fixture(file), dir.path().join(file)).unwrap();
    }
    let path = dir.path().join("scene.gltf");
    std::fs::write(&path, changed).unwrap();
    let loaded = formats::load(&path).unwrap();
    assert_eq!(
        loaded.description.warnings,
        [format!(
            "{}: material 'checker': a texture transform that is not finite, ignored",
            path.display()
        )]
    );
    let plain = formats::load(&fixture("scene.gltf")).unwrap().description;
    let uv = Vec2::new(0.3, 0.6);
    assert_eq!(
        loaded.description.materials[0].at(uv),
        plain.materials[0].at(uv)
    );
}

#[test]
fn vertex_colours_that_are_not_finite_are_a_warning_and_are_ignored() {
    let dir = tempfile::tempdir().unwrap();
    let path = support::vertex_coloured_gltf(dir.path(), false);
    // The green corner's red channel (the second colour's first float) becomes NaN.
    let bin = dir.path().join("t.bin");
    let mut bytes = std::fs::read(&bin).unwrap();
    bytes[48..52].copy_from_slice(&f32::NAN.to_le_bytes());
    std::fs::write(&bin, bytes).unwrap();
    let loaded = formats::load(&path).unwrap();
    assert_eq!(
        loaded.description.warnings,
        [format!(
            "{}: mesh 0 primitive 0: vertex colours that are not finite; ignored",
            path.display()
        )]
    );
    // The triangle keeps the renderer's grey, untextured.
    assert!(
        loaded
            .description
            .materials
            .iter()
            .all(|m| m.maps.is_none())
    );
}

/// Three placements (translation, rotation, scale) of a mesh, one mirroring.
const INSTANCES: [([f32; 3], [f32; 4], [f32; 3]); 3] = [
    ([0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0], [1.0, 1.0, 1.0]),
    ([1.5, -0.25, -0.5], [0.0, 0.6, 0.0, 0.8], [0.5, 1.25, 1.0]),
    (
        [-1.25, 0.5, 0.25],
        [0.28, 0.0, 0.96, 0.0],
        [-1.0, 0.75, 1.5],
    ),
];

/// A glTF file (in `dir`, named `name`) of a triangle with normals placed by the
/// three [`INSTANCES`] under a parent node that turns and moves them: through
/// `EXT_mesh_gpu_instancing` on one node (`instancing`), or as three plain nodes.
/// `scale_count` is the count the SCALE accessor claims; `translation` replaces the
/// second instance's translation.
fn gpu_instanced(
    dir: &Path,
    name: &str,
    instancing: bool,
    scale_count: usize,
    translation: [f32; 3],
) -> PathBuf {
    let mut instances = INSTANCES;
    instances[1].0 = translation;
    let mut floats: Vec<f32> = vec![
        -0.5, -0.5, 0.0, 0.5, -0.5, 0.0, 0.0, 0.6, 0.1, // positions
        0.0, 0.0, 1.0, 0.3, 0.0, 1.0, 0.0, 0.3, 1.0, // normals
    ];
    floats.extend(instances.iter().flat_map(|i| i.0));
    floats.extend(instances.iter().flat_map(|i| i.1));
    floats.extend(instances.iter().flat_map(|i| i.2));
    let bin: Vec<u8> = floats.iter().flat_map(|f| f.to_le_bytes()).collect();
    std::fs::write(dir.join(format!("{name}.bin")), &bin).unwrap();
    let children: Vec<String> = match instancing {
        true => vec![r#"{"mesh": 0, "extensions": {"EXT_mesh_gpu_instancing": {"attributes": {"TRANSLATION": 2, "ROTATION": 3, "SCALE": 4}}}}"#.into()],
        false => instances
            .iter()
            .map(|(t, r, s)| format!(r#"{{"mesh": 0, "translation": {t:?}, "rotation": {r:?}, "scale": {s:?}}}"#))
            .collect(),
    };
    let child_indices: Vec<usize> = (1..=children.len()).collect();
    let gltf = format!(
        r#"{{
  "asset": {{"version": "2.0"}},
  "extensionsUsed": ["EXT_mesh_gpu_instancing"],
  "scene": 0,
  "scenes": [{{"nodes": [0]}}],
  "nodes": [{{"translation": [0.1, 0.2, -3.0], "rotation": [0.0, 0.0, 0.28, 0.96], "children": {child_indices:?}}}, {children}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0, "NORMAL": 1}}}}]}}],
  "buffers": [{{"uri": "{name}.bin", "byteLength": {len}}}],
  "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 72}}, {{"buffer": 0, "byteOffset": 72, "byteLength": 120}}],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [-0.5, -0.5, 0], "max": [0.5, 0.6, 0.1]}},
    {{"bufferView": 0, "byteOffset": 36, "componentType": 5126, "count": 3, "type": "VEC3"}},
    {{"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC3"}},
    {{"bufferView": 1, "byteOffset": 36, "componentType": 5126, "count": 3, "type": "VEC4"}},
    {{"bufferView": 1, "byteOffset": 84, "componentType": 5126, "count": {scale_count}, "type": "VEC3"}}
  ]
}}"#,
        children = children.join(", "),
        len = bin.len(),
    );
    let path = dir.join(format!("{name}.gltf"));
    std::fs::write(&path, gltf).unwrap();
    path
}

#[test]
fn gpu_instancing_renders_as_the_same_placements_written_as_nodes() {
    use raytracer::{Aov, RenderOptions, render, render_outputs};
    let dir = tempfile::tempdir().unwrap();
    let t = INSTANCES[1].0;
    let instanced = formats::load(&gpu_instanced(dir.path(), "i", true, 3, t)).unwrap();
    let nodes = formats::load(&gpu_instanced(dir.path(), "n", false, 3, t)).unwrap();
    let instanced = instanced.description;
    assert!(instanced.warnings.is_empty(), "{:?}", instanced.warnings);
    // Placed through instances of one mesh, not written out three times.
    assert_eq!((instanced.meshes.len(), instanced.instances.len()), (1, 3));
    assert!(instanced.triangles.is_empty());
    let options = RenderOptions {
        width: 48,
        height: 36,
        look_from: Vec3::new(0.0, 0.0, -1.2),
        look_to: Vec3::new(0.0, 0.0, -3.0),
        ..RenderOptions::default()
    };
    let images = [instanced, nodes.description].map(|mut description| {
        description.add_default_light(&options);
        let scene = Scene::build(description, &BvhParams::default());
        let aovs = [Aov::Depth, Aov::Normal, Aov::ObjectId];
        let outputs = render_outputs(&scene, &options, &aovs);
        let covered = (outputs.aovs.object_id.as_ref().unwrap().iter())
            .filter(|&&id| id >= 0)
            .count();
        (render(&scene, &options).pixels, outputs, covered)
    });
    let [(colour, outputs, covered), (colour_nodes, outputs_nodes, _)] = images;
    assert!(covered > 100, "the copies cover {covered} pixels");
    assert!(colour == colour_nodes, "full mode differs");
    assert!(outputs.aovs.depth == outputs_nodes.aovs.depth);
    assert!(outputs.aovs.normal == outputs_nodes.aovs.normal);
}

#[test]
fn gpu_instancing_with_mismatched_or_non_finite_attributes_is_an_error_naming_the_node() {
    let dir = tempfile::tempdir().unwrap();
    let t = INSTANCES[1].0;
    let path = gpu_instanced(dir.path(), "count", true, 2, t);
    let error = formats::load(&path).unwrap_err().to_string();
    assert!(
        error.contains(&path.display().to_string())
            && error.contains(
                "node 1: EXT_mesh_gpu_instancing: TRANSLATION has 3 elements, ROTATION 3, SCALE 2"
            ),
        "{error}"
    );
    let path = gpu_instanced(dir.path(), "nan", true, 3, [0.0, Float::NAN, 0.0]);
    let error = formats::load(&path).unwrap_err().to_string();
    assert!(
        error.contains(&path.display().to_string())
            && error.contains(
                "node 1: EXT_mesh_gpu_instancing: instance 1: a TRANSLATION that is not finite"
            ),
        "{error}"
    );
}

#[test]
fn a_scene_without_nodes_is_an_empty_scene_not_an_error() {
    // glTF 2.0 makes a scene's `nodes` optional (assimp's
    // `TestNoRootNode/SceneWithoutNodes.gltf` is such a file).
    let dir = tempfile::tempdir().unwrap();
    let empty = dir.path().join("empty.gltf");
    std::fs::write(
        &empty,
        r#"{"asset": {"version": "2.0"}, "scene": 0, "scenes": [{}]}"#,
    )
    .unwrap();
    let loaded = formats::load(&empty).unwrap_or_else(|e| panic!("{e}"));
    assert!(loaded.description.triangles.is_empty());
    // Beside a scene that has nodes, in a GLB: the binary chunk and the rest of the
    // file are read as ever.
    let (mut json, bin) =
        crate::gltf_compression::split_glb(&std::fs::read(fixture("scene.glb")).unwrap());
    let scene = json["scenes"][json["scene"].as_u64().unwrap_or(0) as usize].clone();
    json["scenes"] = gltf::json::Value::Array(vec![
        gltf::json::deserialize::from_str(r#"{"name": "no nodes"}"#).unwrap(),
        scene,
    ]);
    json["scene"] = 1.into();
    let two = dir.path().join("two.glb");
    std::fs::write(&two, crate::gltf_compression::join_glb(&json, &bin)).unwrap();
    let expected = formats::load(&fixture("scene.glb")).unwrap().description;
    let read = formats::load(&two)
        .unwrap_or_else(|e| panic!("{e}"))
        .description;
    assert_eq!(read.triangles.len(), expected.triangles.len());
    assert!(!read.triangles.is_empty());
    assert_eq!(read.positions, expected.positions);
    // A file the leniency does not mend keeps its own error.
    let error = error_of(
        "scenes.gltf",
        br#"{"asset": {"version": "2.0"}, "scenes": 3}"#,
    );
    assert!(error.contains("not a valid glTF file"), "{error}");
}
