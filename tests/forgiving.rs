//! What other tools write and read renders here too, with one warning per kind naming
//! the file and line: OBJ `l` and `p` elements and faces of fewer than 3 vertices are
//! skipped, an MTL `Ns` below 0 is read as 0, a missing `.mtl` leaves its materials at
//! the default, an unknown PLY header line is skipped, the triangles at vertices whose
//! position is NaN or infinite are dropped, and those at NaN or infinite normals or
//! texture coordinates lose them. (Truly broken input stays an error:
//! `tests/malformed.rs`.) Scenes: `tests/data/forgiving/`, or written by the test.

use crate::support;

use std::path::{Path, PathBuf};

use assert_cmd::Command;

fn forgiving_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/forgiving")
}

/// Renders `scene` (in the forgiving folder) looking down -z from the origin; returns
/// the warnings printed, in order, and the image.
fn render(scene: &str) -> (Vec<String>, Vec<u8>) {
    render_in(&forgiving_dir(), scene)
}

/// [`render`] for a scene in `dir`.
fn render_in(dir: &Path, scene: &str) -> (Vec<String>, Vec<u8>) {
    let out_dir = tempfile::tempdir().unwrap();
    let out = out_dir.path().join("out.png");
    let output = Command::cargo_bin("raytracer")
        .unwrap()
        .current_dir(dir)
        .args(["render", scene, "-o"])
        .arg(&out)
        .args(["--width", "32", "--height", "24", "-j", "1"])
        .args(["--look-from", "0,0,0", "--look-to", "0,0,-1"])
        .output()
        .unwrap();
    let stderr = String::from_utf8(output.stderr).unwrap();
    assert!(output.status.success(), "{scene}: {stderr}");
    let warnings = stderr
        .lines()
        .map(|line| {
            line.strip_prefix("warning: ")
                .unwrap_or_else(|| panic!("not a warning: {line}"))
                .to_string()
        })
        .collect();
    (warnings, support::read_png(&out).2)
}

/// The middle pixel's red, green and blue.
fn centre(rgb: &[u8]) -> [u8; 3] {
    let at = 3 * (12 * 32 + 16);
    [rgb[at], rgb[at + 1], rgb[at + 2]]
}

#[test]
fn lines_points_and_short_faces_are_skipped_with_one_warning_per_kind() {
    let (warnings, rgb) = render("skipped-elements.obj");
    // The reader's warnings in file order, then the summary of what it skipped.
    assert_eq!(
        warnings,
        [
            "skipped-elements.obj:6: skipped 2 line elements ('l'): lines have no area to render",
            "skipped-elements.obj:8: skipped 1 point element ('p'): points have no area to render",
            "skipped-elements.obj:9: skipped 2 faces of fewer than 3 vertices",
        ]
    );
    // The triangle still renders, lit, in the default grey.
    let [r, g, b] = centre(&rgb);
    assert!(r > 50 && r == g && g == b, "{r} {g} {b}");
}

#[test]
fn numbers_followed_by_other_characters_are_read_by_their_leading_number() {
    // As assimp's `number_formats.obj` spells them (`3.1+e2`), and `1,5`: assimp,
    // tinyobjloader and Blender read the number the token starts with.
    let (warnings, rgb) = render("trailing-characters.obj");
    assert_eq!(
        warnings,
        [
            "trailing-characters.obj:4: read 4 vertex lines with a number followed by other \
             characters (such as '3.1+e2') by the leading number (3.1), as assimp, \
             tinyobjloader and Blender do",
        ]
    );
    // The triangle lies at z = -3 (`-3.0+e1` read as -3.0, not -30), so it fills the
    // middle of the image, lit.
    let [r, g, b] = centre(&rgb);
    assert!(r > 50 && r == g && g == b, "{r} {g} {b}");
}

#[test]
fn a_missing_material_library_leaves_the_default_material_with_one_warning() {
    let (warnings, rgb) = render("missing-mtl.obj");
    // One warning, not one per material name the library would have defined.
    assert_eq!(
        warnings,
        [
            "missing-mtl.obj:1: material library nowhere.mtl not found; its materials get the default material"
        ]
    );
    let [r, g, b] = centre(&rgb);
    assert!(r > 50 && r == g && g == b, "{r} {g} {b}");
}

#[test]
fn a_scene_file_can_still_give_a_mesh_with_a_missing_library_its_material() {
    let (warnings, rgb) = render("missing-mtl.toml");
    // The warning is about the mesh's own materials, which the scene file replaced.
    assert!(warnings.is_empty(), "{warnings:?}");
    let [r, g, b] = centre(&rgb);
    assert!(g > 50 && r == 0 && b == 0, "{r} {g} {b}");
}

#[test]
fn a_negative_phong_exponent_is_read_as_zero() {
    let (warnings, rgb) = render("negative-ns.obj");
    assert_eq!(
        warnings,
        ["negative-ns.mtl:4: 'Ns' below 0 read as 0 (1 line)"]
    );
    assert!(centre(&rgb)[0] > 50);
}

#[test]
fn an_unknown_ply_header_line_is_skipped() {
    let (warnings, rgb) = render("created-by.ply");
    assert_eq!(
        warnings,
        [
            "created-by.ply:3: skipped 1 header line of unknown keyword ('Created')",
            "the scene has no lights (no light sources, no emitting surfaces): lit by a default light rig at the camera (--no-default-light turns it off)"
        ]
    );
    assert!(centre(&rgb)[0] > 50);
}

/// A vertex list and faces (0-based corners) with two vertices the reader cannot
/// place (`bad`), and the faces left once those using them are dropped.
struct NonFinite {
    vertices: Vec<[f32; 3]>,
    faces: Vec<Vec<u32>>,
    bad: [usize; 2],
}

impl NonFinite {
    fn new() -> NonFinite {
        NonFinite {
            // A quad and a triangle in view, and vertices 4 (NaN) and 6 (beyond f32)
            // used by a triangle each and by a concave pentagon.
            vertices: vec![
                [-1.0, -1.0, -3.0],
                [1.0, -1.0, -3.0],
                [1.0, 1.0, -3.0],
                [-1.0, 1.0, -3.0],
                [f32::NAN, 0.0, -3.0],
                [0.0, 2.0, -3.0],
                [f32::INFINITY, 0.5, -3.0],
            ],
            faces: vec![
                vec![0, 1, 2, 3],
                vec![0, 1, 4],
                vec![3, 2, 5],
                vec![4, 2, 3],
                vec![0, 6, 2],
                vec![0, 1, 6, 2, 5],
            ],
            bad: [4, 6],
        }
    }

    /// The same scene written without the faces using a bad vertex, the bad
    /// vertices at a finite place no face uses: what the reader should make of it.
    fn without_bad(&self) -> NonFinite {
        let mut vertices = self.vertices.clone();
        for &b in &self.bad {
            vertices[b] = [0.0, 0.0, -3.0];
        }
        let faces = (self.faces.iter())
            .filter(|f| f.iter().all(|c| !self.bad.contains(&(*c as usize))))
            .cloned()
            .collect();
        NonFinite {
            vertices,
            faces,
            bad: self.bad,
        }
    }

    fn obj(&self) -> String {
        let mut text = String::new();
        for (i, v) in self.vertices.iter().enumerate() {
            // As scanners and converters write them: `nan` and a number past f32.
            let x = match v[0] {
                x if x.is_nan() => "nan".to_string(),
                x if x.is_infinite() => "1e39".to_string(),
                x => x.to_string(),
            };
            text += &format!("v {x} {} {}  # {i}\n", v[1], v[2]);
        }
        for f in &self.faces {
            let corners: Vec<String> = f.iter().map(|c| (c + 1).to_string()).collect();
            text += &format!("f {}\n", corners.join(" "));
        }
        text
    }

    fn ply_header(&self, format: &str) -> String {
        format!(
            "ply\nformat {format} 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
            self.vertices.len(),
            self.faces.len()
        )
    }

    /// Vertex 4 is NaN in its normal (as the first NaN of Assimp's `pond.0.ply`), not
    /// its position: a vertex that cannot be shaded goes the same way.
    fn normal(&self, i: usize) -> [f32; 3] {
        match self.vertices[i][0].is_nan() {
            true => [f32::NAN, 0.0, 1.0],
            false => [0.0, 0.0, 1.0],
        }
    }

    fn ply_ascii(&self) -> Vec<u8> {
        let mut text = self.ply_header("ascii");
        for (i, v) in self.vertices.iter().enumerate() {
            let [a, b, c] = self.normal(i);
            let x = match v[0] {
                x if x.is_infinite() => "inf".to_string(),
                x => x.to_string(),
            };
            text += &format!("{x} {} {} {a} {b} {c}\n", v[1], v[2]);
        }
        for f in &self.faces {
            let corners: Vec<String> = f.iter().map(u32::to_string).collect();
            text += &format!("{} {}\n", f.len(), corners.join(" "));
        }
        text.into_bytes()
    }

    fn ply_binary(&self) -> Vec<u8> {
        let mut bytes = self.ply_header("binary_little_endian").into_bytes();
        for (i, v) in self.vertices.iter().enumerate() {
            let x = if v[0].is_nan() { 0.0 } else { v[0] };
            for value in [x, v[1], v[2]].into_iter().chain(self.normal(i)) {
                bytes.extend(value.to_le_bytes());
            }
        }
        for f in &self.faces {
            bytes.push(f.len() as u8);
            for c in f {
                bytes.extend((*c as i32).to_le_bytes());
            }
        }
        bytes
    }

    /// A glTF file of the faces as triangle fans, not indexed, its buffer in
    /// `dir/stem.bin`; without the triangles (glTF has no polygons) using a bad
    /// vertex unless `all`.
    fn gltf(&self, dir: &Path, stem: &str, all: bool) -> String {
        let mut bin = Vec::new();
        let mut count = 0;
        let fans = self
            .faces
            .iter()
            .flat_map(|f| (1..f.len() - 1).map(|k| [f[0], f[k], f[k + 1]]));
        for triangle in fans.filter(|t| all || t.iter().all(|c| !self.bad.contains(&(*c as usize))))
        {
            for c in triangle {
                for value in self.vertices[c as usize] {
                    bin.extend(value.to_le_bytes());
                }
                count += 1;
            }
        }
        std::fs::write(dir.join(format!("{stem}.bin")), &bin).unwrap();
        format!(
            r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0]}}],
  "nodes": [{{"mesh": 0}}], "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}}}]}}],
  "buffers": [{{"uri": "{stem}.bin", "byteLength": {len}}}],
  "bufferViews": [{{"buffer": 0, "byteLength": {len}}}],
  "accessors": [{{"bufferView": 0, "componentType": 5126, "count": {count}, "type": "VEC3",
    "min": [-1, -1, -3], "max": [1, 2, -3]}}]}}"#,
            len = bin.len()
        )
    }
}

/// Renders `bad` and `good` (file contents, written into one folder as `name.EXT`
/// and `good.EXT`) and checks that they render alike and that the first gives one
/// warning more, naming it with the counts, `dropped` triangles.
fn renders_as_without_its_bad_vertices(ext: &str, bad: &[u8], good: &[u8], dropped: usize) {
    let dir = tempfile::tempdir().unwrap();
    let name = format!("non-finite.{ext}");
    let good_name = format!("good.{ext}");
    std::fs::write(dir.path().join(&name), bad).unwrap();
    std::fs::write(dir.path().join(&good_name), good).unwrap();
    let (warnings, rgb) = render_in(dir.path(), &name);
    let (good_warnings, good_rgb) = render_in(dir.path(), &good_name);
    assert_eq!(support::differences(&rgb, &good_rgb), (0, 0), "{ext}");
    // Something was rendered: not a blank image on both sides.
    assert!(rgb.chunks(3).any(|p| p != [0, 0, 0]), "{ext}");
    let expected = format!(
        "{name}: 2 vertices with a non-finite coordinate (NaN or infinite); the \
         {dropped} triangles using them are dropped"
    );
    let mut without = warnings.clone();
    let at = without.iter().position(|w| *w == expected);
    assert!(at.is_some(), "{ext}: {warnings:?}");
    without.remove(at.unwrap());
    let renamed: Vec<String> = good_warnings
        .iter()
        .map(|w| w.replace(&good_name, &name))
        .collect();
    assert_eq!(without, renamed, "{ext}");
}

#[test]
fn obj_triangles_at_non_finite_vertices_are_dropped_with_one_warning() {
    let scene = NonFinite::new();
    let good = scene.without_bad();
    // Three triangles and the pentagon's three.
    renders_as_without_its_bad_vertices("obj", scene.obj().as_bytes(), good.obj().as_bytes(), 6);
}

#[test]
fn ply_triangles_at_non_finite_vertices_are_dropped_with_one_warning() {
    let scene = NonFinite::new();
    let good = scene.without_bad();
    renders_as_without_its_bad_vertices("ply", &scene.ply_ascii(), &good.ply_ascii(), 6);
    renders_as_without_its_bad_vertices("ply", &scene.ply_binary(), &good.ply_binary(), 6);
}

#[test]
fn gltf_triangles_at_non_finite_positions_are_dropped_with_one_warning() {
    let dir = tempfile::tempdir().unwrap();
    let scene = NonFinite::new();
    let bad = scene.gltf(dir.path(), "non-finite", true);
    let good = scene.gltf(dir.path(), "good", false);
    // The buffers are named by the test's folder; both files go next to them.
    for (name, text) in [("non-finite.gltf", &bad), ("good.gltf", &good)] {
        std::fs::write(dir.path().join(name), text).unwrap();
    }
    let (warnings, rgb) = render_in(dir.path(), "non-finite.gltf");
    let (good_warnings, good_rgb) = render_in(dir.path(), "good.gltf");
    assert_eq!(support::differences(&rgb, &good_rgb), (0, 0));
    assert_eq!(
        warnings.len(),
        good_warnings.len() + 1,
        "{warnings:?} {good_warnings:?}"
    );
    // Unindexed: each of the five triangles has its own copy of its bad corner.
    assert!(
        warnings.contains(
            &"non-finite.gltf: 5 vertices with a non-finite coordinate (NaN or infinite); the 5 \
          triangles using them are dropped"
                .to_string()
        )
    );
}

/// One corner of [`AttributeScene`]: position, normal, texture coordinates.
type Corner = ([f32; 3], [f32; 3], [f32; 2]);

/// Four textured triangles with tilted normals in front of the camera, unindexed:
/// triangle 1 has a NaN in one corner's normal and triangle 2 an infinity in one
/// corner's texture coordinates, where a good scene has no normals (triangle 1) or
/// no texture coordinates (triangle 2) at all.
struct AttributeScene {
    triangles: Vec<[Corner; 3]>,
}

impl AttributeScene {
    fn new(bad: bool) -> AttributeScene {
        let corner =
            |x: f32, y: f32, n: [f32; 3]| ([x, y, -3.0], n, [x / 3.0 + 0.5, y / 2.0 + 0.5]);
        let (tilt_a, tilt_b) = ([0.3, 0.2, 1.0], [-0.2, 0.3, 1.0]);
        let mut triangles = vec![
            [
                corner(-1.5, -1.0, tilt_a),
                corner(0.0, -1.0, tilt_b),
                corner(0.0, 1.0, tilt_a),
            ],
            [
                corner(-1.5, -1.0, tilt_b),
                corner(0.0, 1.0, tilt_a),
                corner(-1.5, 1.0, tilt_b),
            ],
            [
                corner(0.0, -1.0, tilt_a),
                corner(1.5, -1.0, tilt_b),
                corner(1.5, 1.0, tilt_b),
            ],
            [
                corner(0.0, -1.0, tilt_b),
                corner(1.5, 1.0, tilt_a),
                corner(0.0, 1.0, tilt_b),
            ],
        ];
        if bad {
            triangles[1][1].1[0] = f32::NAN;
            triangles[2][2].2[1] = f32::INFINITY;
        }
        AttributeScene { triangles }
    }

    /// Whether triangle `t` has normals, and texture coordinates, in the good scene.
    fn has(t: usize) -> (bool, bool) {
        (t != 1, t != 2)
    }

    /// The scene as OBJ with `tex.mtl`; the good one leaves out the `vn` or `vt`
    /// index of its faces, as exporters write faces without them.
    fn obj(&self, bad: bool) -> String {
        let mut text = String::from("mtllib tex.mtl\nusemtl tex\n");
        let number = |x: f32| match x {
            x if x.is_nan() => "nan".to_string(),
            x if x.is_infinite() => "inf".to_string(),
            x => x.to_string(),
        };
        for (t, triangle) in self.triangles.iter().enumerate() {
            for (p, n, uv) in triangle {
                text += &format!("v {} {} {}\n", p[0], p[1], p[2]);
                text += &format!("vn {} {} {}\n", number(n[0]), n[1], n[2]);
                text += &format!("vt {} {}\n", uv[0], number(uv[1]));
            }
            let (normals, texcoords) = if bad { (true, true) } else { Self::has(t) };
            let corners: Vec<String> = (1..=3)
                .map(|k| {
                    let i = 3 * t + k;
                    match (texcoords, normals) {
                        (true, true) => format!("{i}/{i}/{i}"),
                        (true, false) => format!("{i}/{i}"),
                        (false, true) => format!("{i}//{i}"),
                        (false, false) => format!("{i}"),
                    }
                })
                .collect();
            text += &format!("f {}\n", corners.join(" "));
        }
        text
    }

    /// The scene as glTF with its buffer in `dir/stem.bin` and the texture `tex.png`:
    /// the bad one as one primitive, the good one with triangles 1 and 2 as primitives
    /// of their own, without normals or texture coordinates.
    fn gltf(&self, dir: &Path, stem: &str, bad: bool) -> String {
        let groups: Vec<(Vec<usize>, (bool, bool))> = match bad {
            true => vec![(vec![0, 1, 2, 3], (true, true))],
            false => vec![
                (vec![0, 3], (true, true)),
                (vec![1], Self::has(1)),
                (vec![2], Self::has(2)),
            ],
        };
        let mut bin: Vec<u8> = Vec::new();
        let (mut views, mut accessors, mut primitives) = (vec![], vec![], vec![]);
        let mut add = |bin: &mut Vec<u8>, values: Vec<f32>, kind: &str| {
            let count = values.len() / if kind == "VEC3" { 3 } else { 2 };
            views.push(format!(
                r#"{{"buffer": 0, "byteOffset": {}, "byteLength": {}}}"#,
                bin.len(),
                4 * values.len()
            ));
            bin.extend(values.iter().flat_map(|v| v.to_le_bytes()));
            let bounds = if kind == "VEC3" {
                r#", "min": [-1.5, -1, -3], "max": [1.5, 1, -3]"#
            } else {
                ""
            };
            accessors.push(format!(
                r#"{{"bufferView": {}, "componentType": 5126, "count": {count}, "type": "{kind}"{bounds}}}"#,
                views.len() - 1
            ));
            accessors.len() - 1
        };
        for (triangles, (normals, texcoords)) in groups {
            let corners = || triangles.iter().flat_map(|&t| self.triangles[t]);
            let mut attributes = vec![format!(
                r#""POSITION": {}"#,
                add(&mut bin, corners().flat_map(|c| c.0).collect(), "VEC3")
            )];
            if normals {
                let at = add(&mut bin, corners().flat_map(|c| c.1).collect(), "VEC3");
                attributes.push(format!(r#""NORMAL": {at}"#));
            }
            if texcoords {
                let at = add(&mut bin, corners().flat_map(|c| c.2).collect(), "VEC2");
                attributes.push(format!(r#""TEXCOORD_0": {at}"#));
            }
            primitives.push(format!(
                r#"{{"attributes": {{{}}}, "material": 0}}"#,
                attributes.join(", ")
            ));
        }
        std::fs::write(dir.join(format!("{stem}.bin")), &bin).unwrap();
        format!(
            r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0]}}],
  "nodes": [{{"mesh": 0}}], "meshes": [{{"primitives": [{}]}}],
  "materials": [{{"pbrMetallicRoughness": {{"baseColorTexture": {{"index": 0}}, "metallicFactor": 0}}}}],
  "textures": [{{"source": 0}}], "images": [{{"uri": "tex.png"}}],
  "buffers": [{{"uri": "{stem}.bin", "byteLength": {}}}],
  "bufferViews": [{}], "accessors": [{}]}}"#,
            primitives.join(", "),
            bin.len(),
            views.join(", "),
            accessors.join(", ")
        )
    }
}

/// Writes `bad` and `good` (scene files named `non-finite.EXT` and `good.EXT`) into
/// `dir`, with a 4x4 texture of distinct texels, renders them, and checks that they
/// render alike, lit and textured, and that the bad one gives the one warning more.
fn renders_as_without_its_bad_attributes(dir: &Path, ext: &str, bad: &str, good: &str) {
    let texels: Vec<u8> = (0..48).map(|i| (i * 37 % 200 + 40) as u8).collect();
    support::write_png(&dir.join("tex.png"), 4, 4, 3, &texels);
    std::fs::write(
        dir.join("tex.mtl"),
        "newmtl tex\nKd 1 1 1\nmap_Kd tex.png\n",
    )
    .unwrap();
    let name = format!("non-finite.{ext}");
    std::fs::write(dir.join(&name), bad).unwrap();
    std::fs::write(dir.join(format!("good.{ext}")), good).unwrap();
    let (warnings, rgb) = render_in(dir, &name);
    let (good_warnings, good_rgb) = render_in(dir, &format!("good.{ext}"));
    assert_eq!(support::differences(&rgb, &good_rgb), (0, 0), "{ext}");
    // Textured: many colours, not one flat grey.
    let mut colours: Vec<&[u8]> = rgb.chunks(3).collect();
    colours.sort_unstable();
    colours.dedup();
    assert!(colours.len() > 8, "{ext}: {} colours", colours.len());
    let expected = format!(
        "{name}: 1 normal with a non-finite coordinate (NaN or infinite); the 1 triangle \
         using it is shaded flat; 1 texture coordinate with a non-finite coordinate (NaN or \
         infinite); the 1 triangle using it is left without texture coordinates (its \
         textures read at (0, 0))"
    );
    let good_name = format!("good.{ext}");
    let mut expected_warnings: Vec<String> = good_warnings
        .iter()
        .map(|w| w.replace(&good_name, &name))
        .collect();
    expected_warnings.push(expected);
    let mut sorted = warnings.clone();
    sorted.sort();
    expected_warnings.sort();
    assert_eq!(sorted, expected_warnings, "{ext}");
}

#[test]
fn obj_non_finite_normals_and_texture_coordinates_leave_their_triangles_with_one_warning() {
    let dir = tempfile::tempdir().unwrap();
    let (bad, good) = (AttributeScene::new(true), AttributeScene::new(false));
    renders_as_without_its_bad_attributes(dir.path(), "obj", &bad.obj(true), &good.obj(false));
}

#[test]
fn gltf_non_finite_normals_and_texture_coordinates_leave_their_triangles_with_one_warning() {
    let dir = tempfile::tempdir().unwrap();
    let (bad, good) = (AttributeScene::new(true), AttributeScene::new(false));
    let bad = bad.gltf(dir.path(), "non-finite", true);
    let good = good.gltf(dir.path(), "good", false);
    renders_as_without_its_bad_attributes(dir.path(), "gltf", &bad, &good);
}
