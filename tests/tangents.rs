//! Vertex tangents: the frame normal maps tilt the shading normal in. glTF's
//! `TANGENT` (float, and `KHR_mesh_quantization`'s normalized shorts) gives it,
//! placed by a node or an instance as a direction in the surface, its `w` the
//! bitangent's sign; without it (or with unusable values, with a warning) MikkTSpace
//! makes one per vertex, so that a smooth low-poly mesh stays smooth under a normal
//! map where a frame per triangle jumps at every edge.

use crate::support::write_png;

use std::path::{Path, PathBuf};

use raytracer::Scene;
use raytracer::bvh::BvhParams;
use raytracer::formats;
use raytracer::math::{Float, Ray, Vec3};

/// A mesh as glTF stores it (`uv` with `v` down the image).
struct Mesh {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    uvs: Vec<[f32; 2]>,
    tangents: Option<Tangents>,
    indices: Vec<u32>,
}

enum Tangents {
    Float(Vec<[f32; 4]>),
    /// `KHR_mesh_quantization`: normalized signed shorts.
    Short(Vec<[i16; 4]>),
}

/// A quad in the plane z = 0 facing +z, from -1 to 1, its texture's `u` along +x
/// and its image's up along +y, with `tangents` at its four corners.
fn quad(tangents: Option<Tangents>) -> Mesh {
    Mesh {
        positions: vec![
            [-1.0, -1.0, 0.0],
            [1.0, -1.0, 0.0],
            [1.0, 1.0, 0.0],
            [-1.0, 1.0, 0.0],
        ],
        normals: vec![[0.0, 0.0, 1.0]; 4],
        uvs: vec![[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]],
        tangents,
        indices: vec![0, 1, 2, 0, 2, 3],
    }
}

/// The tangent-space normal a texel `rgb` of a normal map stands for.
fn local(rgb: [u8; 3]) -> Vec3 {
    Vec3::from(rgb.map(|c| c as Float / 255.0 * 2.0 - 1.0)).normalize()
}

/// The normal `texel` stands for in the frame `t`, `b`, `n`.
fn tilt(texel: [u8; 3], t: Vec3, b: Vec3, n: Vec3) -> Vec3 {
    let l = local(texel);
    (t * l.x + b * l.y + n * l.z).normalize()
}

/// Tilts by 30 degrees towards the tangent (red) and towards the bitangent (green).
const TOWARDS_TANGENT: [u8; 3] = [191, 128, 238];
const TOWARDS_BITANGENT: [u8; 3] = [128, 191, 238];

/// Writes `name.gltf` (and its `.bin`, and a 1 x 1 normal map of `texel`) into `dir`:
/// `mesh` with a material whose normal map is that texel, placed by `nodes` (a JSON
/// array of nodes, each `"mesh": 0`); returns its path.
fn write_gltf(dir: &Path, name: &str, mesh: &Mesh, texel: [u8; 3], nodes: &str) -> PathBuf {
    write_gltf_with(dir, name, mesh, texel, nodes, "")
}

/// [`write_gltf`] with `normal_texture` (JSON members, each followed by a comma)
/// added to the material's `normalTexture`: its texture transform.
fn write_gltf_with(
    dir: &Path,
    name: &str,
    mesh: &Mesh,
    texel: [u8; 3],
    nodes: &str,
    normal_texture: &str,
) -> PathBuf {
    write_png(&dir.join(format!("{name}.png")), 1, 1, 3, &texel);
    let mut bin: Vec<u8> = Vec::new();
    let mut views = Vec::new();
    let mut view = |bin: &mut Vec<u8>, bytes: Vec<u8>| {
        views.push(format!(
            r#"{{"buffer": 0, "byteOffset": {}, "byteLength": {}}}"#,
            bin.len(),
            bytes.len()
        ));
        bin.extend(bytes);
        views.len() - 1
    };
    let floats = |values: &[f32]| values.iter().flat_map(|x| x.to_le_bytes()).collect();
    let count = mesh.positions.len();
    let position = view(&mut bin, floats(mesh.positions.as_flattened()));
    let normal = view(&mut bin, floats(mesh.normals.as_flattened()));
    let uv = view(&mut bin, floats(mesh.uvs.as_flattened()));
    let index = view(
        &mut bin,
        mesh.indices.iter().flat_map(|i| i.to_le_bytes()).collect(),
    );
    let (min, max) = mesh.positions.iter().fold(
        ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]),
        |(lo, hi), p| {
            (
                std::array::from_fn(|k| lo[k].min(p[k])),
                std::array::from_fn(|k| hi[k].max(p[k])),
            )
        },
    );
    let mut accessors = vec![
        format!(
            r#"{{"bufferView": {position}, "componentType": 5126, "count": {count}, "type": "VEC3", "min": {min:?}, "max": {max:?}}}"#
        ),
        format!(
            r#"{{"bufferView": {normal}, "componentType": 5126, "count": {count}, "type": "VEC3"}}"#
        ),
        format!(
            r#"{{"bufferView": {uv}, "componentType": 5126, "count": {count}, "type": "VEC2"}}"#
        ),
        format!(
            r#"{{"bufferView": {index}, "componentType": 5125, "count": {}, "type": "SCALAR"}}"#,
            mesh.indices.len()
        ),
    ];
    let mut attributes = r#""POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2"#.to_string();
    let mut extensions = String::new();
    if let Some(tangents) = &mesh.tangents {
        let (bytes, kind) = match tangents {
            Tangents::Float(t) => (floats(t.as_flattened()), "5126"),
            Tangents::Short(t) => {
                extensions = r#""extensionsUsed": ["KHR_mesh_quantization"], "extensionsRequired": ["KHR_mesh_quantization"],"#.into();
                let bytes = t
                    .as_flattened()
                    .iter()
                    .flat_map(|x| x.to_le_bytes())
                    .collect();
                (bytes, r#"5122, "normalized": true"#)
            }
        };
        let tangent = view(&mut bin, bytes);
        accessors.push(format!(
            r#"{{"bufferView": {tangent}, "componentType": {kind}, "count": {count}, "type": "VEC4"}}"#
        ));
        attributes += r#", "TANGENT": 4"#;
    }
    let json = format!(
        r#"{{
  "asset": {{"version": "2.0"}},
  {extensions}
  "buffers": [{{"uri": "{name}.bin", "byteLength": {length}}}],
  "bufferViews": [{views}],
  "accessors": [{accessors}],
  "images": [{{"uri": "{name}.png"}}],
  "textures": [{{"source": 0}}],
  "materials": [{{"normalTexture": {{{normal_texture} "index": 0}}}}],
  "meshes": [{{"primitives": [{{"attributes": {{{attributes}}}, "indices": 3, "material": 0}}]}}],
  "nodes": {nodes},
  "scenes": [{{"nodes": [{roots}]}}],
  "scene": 0
}}"#,
        length = bin.len(),
        views = views.join(", "),
        accessors = accessors.join(",\n    "),
        roots = (0..nodes.matches("\"mesh\"").count())
            .map(|i| i.to_string())
            .collect::<Vec<_>>()
            .join(", "),
    );
    std::fs::write(dir.join(format!("{name}.bin")), bin).unwrap();
    let path = dir.join(format!("{name}.gltf"));
    std::fs::write(&path, json).unwrap();
    path
}

/// The scene of `path` and its warnings.
fn load(path: &Path) -> (Scene, Vec<String>) {
    let loaded = formats::load(path).unwrap_or_else(|e| panic!("{e}"));
    let warnings = loaded.description.warnings.clone();
    (
        Scene::build(loaded.description, &BvhParams::default()),
        warnings,
    )
}

/// The shading normal where the ray from `from` along `dir` hits `scene`.
fn shading_normal(scene: &Scene, from: Vec3, dir: Vec3) -> Vec3 {
    scene
        .intersect(&Ray::new(from, dir))
        .unwrap_or_else(|| panic!("the ray from {from} hits"))
        .ns
}

fn assert_close(got: Vec3, expected: Vec3, what: &str) {
    assert!(
        (got - expected).abs().max_element() < 1e-3,
        "{what}: shading normal {got}, expected {expected}"
    );
}

/// The quad's `TANGENT` runs along +y while its texture's `u` runs along +x: a
/// normal map tilting towards the tangent tilts the shading normal towards +y (a
/// frame from the texture coordinates tilts it towards +x), and one tilting towards
/// the bitangent `w * cross(n, t)` tilts it towards -x with `w = 1` and +x with
/// `w = -1`. Floats and `KHR_mesh_quantization`'s normalized shorts alike.
#[test]
fn gltf_tangents_give_the_normal_maps_frame_and_w_its_bitangent() {
    let dir = tempfile::tempdir().unwrap();
    let from = Vec3::new(0.3, 0.2, 5.0);
    for w in [1.0f32, -1.0] {
        let forms = [
            ("float", Tangents::Float(vec![[0.0, 1.0, 0.0, w]; 4])),
            (
                "short",
                Tangents::Short(vec![[0, i16::MAX, 0, (w * 32767.0) as i16]; 4]),
            ),
        ];
        for (form, tangents) in forms {
            let mesh = quad(Some(tangents));
            let bitangent = Vec3::new(-w, 0.0, 0.0);
            for (texel, what) in [
                (TOWARDS_TANGENT, "towards the tangent"),
                (TOWARDS_BITANGENT, "towards the bitangent"),
            ] {
                let name = format!("quad-{form}-{}-{}", w > 0.0, texel[0]);
                let path = write_gltf(dir.path(), &name, &mesh, texel, r#"[{"mesh": 0}]"#);
                let (scene, warnings) = load(&path);
                assert!(warnings.is_empty(), "{warnings:?}");
                let expected = tilt(texel, Vec3::Y, bitangent, Vec3::Z);
                let got = shading_normal(&scene, from, -Vec3::Z);
                assert_close(got, expected, &format!("{form}, w = {w}, {what}"));
            }
        }
    }
}

/// Tangents are directions in the surface: a node's rotation turns them (the
/// reader places the mesh), and so does an instance's placement (two nodes share
/// the mesh), whose mirroring also turns the bitangent's sign, as glTF's
/// `cross(N n, M t)` runs against the mirrored bitangent `M b`.
#[test]
fn placed_tangents_turn_with_their_node_and_instance() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = quad(Some(Tangents::Float(vec![[0.0, 1.0, 0.0, 1.0]; 4])));
    // A quarter turn about z: the tangent +y becomes -x, the bitangent -x becomes -y.
    let turn = r#""rotation": [0, 0, 0.7071068, 0.7071068]"#;
    let turned = tilt(TOWARDS_TANGENT, -Vec3::X, -Vec3::Y, Vec3::Z);
    let one = write_gltf(
        dir.path(),
        "one",
        &mesh,
        TOWARDS_TANGENT,
        &format!(r#"[{{"mesh": 0, {turn}}}]"#),
    );
    let (scene, _) = load(&one);
    let at = |x: Float, y: Float| Vec3::new(x, y, 5.0);
    assert_close(
        shading_normal(&scene, at(0.2, 0.3), -Vec3::Z),
        turned,
        "node",
    );

    // Two copies: turned at x = 5, mirrored in x at x = -5. Mirrored, the tangent
    // stays +y and the bitangent (green) is M b = +x.
    for texel in [TOWARDS_TANGENT, TOWARDS_BITANGENT] {
        let mirrored = tilt(texel, Vec3::Y, Vec3::X, Vec3::Z);
        let two = write_gltf(
            dir.path(),
            &format!("two-{}", texel[0]),
            &mesh,
            texel,
            &format!(
                r#"[{{"mesh": 0, "translation": [5, 0, 0], {turn}}}, {{"mesh": 0, "translation": [-5, 0, 0], "scale": [-1, 1, 1]}}]"#
            ),
        );
        let (scene, warnings) = load(&two);
        assert!(warnings.is_empty(), "{warnings:?}");
        if texel == TOWARDS_TANGENT {
            let got = shading_normal(&scene, at(5.2, 0.3), -Vec3::Z);
            assert_close(got, turned, "turned instance");
        }
        let got = shading_normal(&scene, at(-5.2, 0.3), -Vec3::Z);
        assert_close(got, mirrored, "mirrored instance");
    }
}

/// A `TANGENT` that is not finite, or has no direction, is not used: one warning
/// naming the file, and the primitive gets MikkTSpace's tangents instead (here
/// along its texture's `u`, +x).
#[test]
fn unusable_gltf_tangents_warn_and_are_made_instead() {
    let dir = tempfile::tempdir().unwrap();
    let along_u = tilt(TOWARDS_TANGENT, Vec3::X, Vec3::Y, Vec3::Z);
    for (name, bad, says) in [
        ("nan", [Float::NAN, 1.0, 0.0, 1.0], "not finite"),
        ("zero", [0.0, 0.0, 0.0, 1.0], "zero length"),
    ] {
        let mut tangents = vec![[0.0, 1.0, 0.0, 1.0]; 4];
        tangents[2] = bad;
        let mesh = quad(Some(Tangents::Float(tangents)));
        let path = write_gltf(dir.path(), name, &mesh, TOWARDS_TANGENT, r#"[{"mesh": 0}]"#);
        let (scene, warnings) = load(&path);
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(
            warnings[0].starts_with(&path.display().to_string())
                && warnings[0].contains(says)
                && warnings[0].contains("MikkTSpace"),
            "{warnings:?}"
        );
        let got = shading_normal(&scene, Vec3::new(0.3, 0.2, 5.0), -Vec3::Z);
        assert_close(got, along_u, name);
    }
    // Without the attribute, the same, silently.
    let path = write_gltf(
        dir.path(),
        "none",
        &quad(None),
        TOWARDS_TANGENT,
        r#"[{"mesh": 0}]"#,
    );
    let (scene, warnings) = load(&path);
    assert!(warnings.is_empty(), "{warnings:?}");
    let got = shading_normal(&scene, Vec3::new(0.3, 0.2, 5.0), -Vec3::Z);
    assert_close(got, along_u, "none");
}

/// A normal map's tilt is in its image's axes: a `KHR_texture_transform` that turns
/// or mirrors the image against the texture coordinates turns or mirrors the tilt
/// with it, so that the shading normal is the one of the same quad with the
/// transform baked into its texture coordinates (and no transform), whose
/// MikkTSpace frame then runs along the image's axes. A quarter turn also has a
/// closed form: the image's `u` runs along glTF's `v`, down the image, which on the
/// quad is -y. Before the transform turned the tilt, every case but the identity
/// tilted the normal towards +x, along the untransformed `u`.
#[test]
fn a_normal_maps_texture_transform_turns_its_tilt_with_the_image() {
    let dir = tempfile::tempdir().unwrap();
    let from = Vec3::new(0.3, 0.2, 5.0);
    // glTF's transform of its coordinates: `R S g + o`, `R` taking (u, v) to
    // (c u + s v, -s u + c v).
    let baked = |g: [f32; 2], angle: f32, scale: [f32; 2], offset: [f32; 2]| {
        let (s, c) = angle.sin_cos();
        let (x, y) = (g[0] * scale[0], g[1] * scale[1]);
        [c * x + s * y + offset[0], -s * x + c * y + offset[1]]
    };
    let quarter = std::f32::consts::FRAC_PI_2;
    let cases = [
        ("identity", 0.0, [1.0, 1.0], [0.0, 0.0]),
        ("quarter turn", quarter, [1.0, 1.0], [0.0, 0.0]),
        ("turned and tiled", 0.7, [3.0, 3.0], [0.25, -0.5]),
        ("mirrored", 0.0, [-1.0, 1.0], [1.0, 0.0]),
        ("turned and mirrored", -2.0, [2.0, -2.0], [0.0, 0.3]),
    ];
    for texel in [TOWARDS_TANGENT, TOWARDS_BITANGENT] {
        for (what, angle, scale, offset) in cases {
            let name = format!("{}-{}", what.replace(' ', "-"), texel[0]);
            let transform = format!(
                r#""extensions": {{"KHR_texture_transform": {{"rotation": {angle}, "scale": {scale:?}, "offset": {offset:?}}}}},"#
            );
            let transformed = write_gltf_with(
                dir.path(),
                &format!("{name}-transformed"),
                &quad(None),
                texel,
                r#"[{"mesh": 0}]"#,
                &transform,
            );
            let mut mesh = quad(None);
            for uv in &mut mesh.uvs {
                *uv = baked(*uv, angle, scale, offset);
            }
            let baked_in = write_gltf(
                dir.path(),
                &format!("{name}-baked"),
                &mesh,
                texel,
                r#"[{"mesh": 0}]"#,
            );
            let (scene, warnings) = load(&transformed);
            assert!(warnings.is_empty(), "{warnings:?}");
            let got = shading_normal(&scene, from, -Vec3::Z);
            let (reference, _) = load(&baked_in);
            let expected = shading_normal(&reference, from, -Vec3::Z);
            assert_close(got, expected, &format!("{what}, texel {texel:?}"));
            if what == "quarter turn" {
                let closed_form = tilt(texel, -Vec3::Y, Vec3::X, Vec3::Z);
                assert_close(got, closed_form, "a quarter turn");
            }
        }
    }
}

/// A pseudo-random number in [0, 1) from `i`.
fn hash(i: u32) -> f32 {
    let mut x = i.wrapping_mul(0x9e37_79b9) ^ 0x85eb_ca6b;
    x ^= x >> 15;
    x = x.wrapping_mul(0x2c1b_3c6d);
    x ^= x >> 12;
    (x >> 8) as f32 / (1 << 24) as f32
}

/// A cylinder of radius 1 about the y axis, 8 sides, 2 rings of quads from y = -1
/// to 1, smooth normals, each vertex's texture coordinates (`u` round, `v` up)
/// moved a little at random, as an artist's unwrap is never regular: per triangle,
/// the frame along the texture's `u` then turns from one triangle to the next.
/// Written as OBJ with an MTL `norm` map of `texel`.
fn cylinder_obj(dir: &Path, texel: [u8; 3]) -> PathBuf {
    let sides = 8;
    let mut obj = String::from("mtllib cylinder.mtl\nusemtl bumpy\n");
    let index = |side: u32, ring: u32| ring * (sides + 1) + side + 1;
    for ring in 0..3u32 {
        for side in 0..=sides {
            let angle = std::f32::consts::TAU * (side % sides) as f32 / sides as f32;
            let (s, c) = angle.sin_cos();
            let y = ring as f32 - 1.0;
            obj += &format!("v {} {y} {}\nvn {} 0 {}\n", s, c, s, c);
            let jitter = |k: u32| (hash(index(side % sides, ring) * 2 + k) - 0.5) * 0.08;
            let (u, v) = (side as f32 / sides as f32, ring as f32 / 2.0);
            obj += &format!("vt {} {}\n", u + jitter(0), v + jitter(1));
        }
    }
    for ring in 0..2 {
        for side in 0..sides {
            let [a, b, c, d] = [
                index(side, ring),
                index(side + 1, ring),
                index(side + 1, ring + 1),
                index(side, ring + 1),
            ];
            for [p, q, r] in [[a, b, c], [a, c, d]] {
                obj += &format!("f {p}/{p}/{p} {q}/{q}/{q} {r}/{r}/{r}\n");
            }
        }
    }
    std::fs::write(dir.join("cylinder.obj"), obj).unwrap();
    write_png(&dir.join("tilt.png"), 1, 1, 3, &texel);
    std::fs::write(
        dir.join("cylinder.mtl"),
        "newmtl bumpy\nKd 0.8 0.8 0.8\nnorm tilt.png\n",
    )
    .unwrap();
    dir.join("cylinder.obj")
}

/// On a smooth low-poly cylinder under a constant tilted normal map (MikkTSpace
/// tangents: OBJ has none of its own), the shading normal is continuous across
/// every edge two triangles share but the texture's seam: the same on both sides within 1e-4, where a
/// frame per triangle jumps. Each shared edge is crossed at its midpoint by two
/// rays a hair either side of it, towards the axis.
#[test]
fn normal_mapped_smooth_meshes_stay_smooth_across_their_edges() {
    let dir = tempfile::tempdir().unwrap();
    for texel in [TOWARDS_TANGENT, TOWARDS_BITANGENT] {
        let (scene, warnings) = load(&cylinder_obj(dir.path(), texel));
        assert!(warnings.is_empty(), "{warnings:?}");
        let sides = 8;
        let corner = |side: u32, y: Float| {
            let angle = std::f32::consts::TAU * (side % sides) as f32 / sides as f32;
            Vec3::new(angle.sin(), y, angle.cos())
        };
        let mut edges = Vec::new();
        for ring in 0..2 {
            let (y0, y1) = (ring as Float - 1.0, ring as Float);
            for side in 0..sides {
                // The side edge between this quad and the next (at corner side + 1;
                // not the texture's seam, where `u` jumps from 1 to 0 and the
                // tangents of each side are their own, as in MikkTSpace), and the
                // quad's diagonal.
                if side + 1 < sides {
                    edges.push((corner(side + 1, y0), corner(side + 1, y1)));
                }
                edges.push((corner(side, y0), corner(side + 1, y1)));
            }
        }
        let mut largest = 0.0f32;
        for (a, b) in edges {
            let mid = (a + b) * 0.5;
            let outward = Vec3::new(mid.x, 0.0, mid.z).normalize();
            // Across the edge, in the surface.
            let across = outward.cross(b - a).normalize();
            let [one, other] = [1.0, -1.0].map(|side: Float| {
                let at = mid + across * (side * 5e-6);
                shading_normal(&scene, at + outward * 2.0, -outward)
            });
            let jump = (one - other).abs().max_element();
            largest = largest.max(jump);
            assert!(
                jump < 1e-4,
                "texel {texel:?}: the shading normal jumps by {jump} across the edge at {mid}: {one} and {other}"
            );
        }
        eprintln!("texel {texel:?}: largest jump across an edge {largest:e}");
    }
}
