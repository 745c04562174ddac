//! glTF's default pose, as three.js and Blender show a file at load: skinned meshes
//! placed by their joints (their node's transform ignored, as the spec says), morph
//! targets blended by their default weights, and one warning for animations, which
//! are not played.

use std::path::{Path, PathBuf};

use raytracer::formats;
use raytracer::math::Vec3;

/// Writes `name.gltf` and `name.bin` into `dir`: one triangle (0,0,0), (1,0,0),
/// (0,1,0) with normals +z, and `json`'s meshes, nodes and extra accessors over the
/// buffer's views (see the layout below).
fn write(dir: &Path, name: &str, json: &str) -> PathBuf {
    let mut bin: Vec<u8> = Vec::new();
    let floats = |bin: &mut Vec<u8>, values: &[f32]| {
        bin.extend(values.iter().flat_map(|f| f.to_le_bytes()));
    };
    // View 0 (bytes 0..36): positions. View 1 (36..72): normals.
    floats(&mut bin, &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
    floats(&mut bin, &[0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0]);
    // View 2 (72..84): JOINTS_0, unsigned bytes: vertices 0 and 1 on joint 0, vertex
    // 2 on joints 0 and 1.
    bin.extend([0u8, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0]);
    // View 3 (84..132): WEIGHTS_0: 1; 2 (scaled to 1); a half each.
    floats(
        &mut bin,
        &[1.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.5, 0.5, 0.0, 0.0],
    );
    // View 4 (132..260): two inverse bind matrices: the identity, and a move by
    // (-3, 0, 0) (joint 1 was bound at x = 3).
    floats(
        &mut bin,
        &[
            1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1.,
        ],
    );
    floats(
        &mut bin,
        &[
            1., 0., 0., 0., 0., 1., 0., 0., 0., 0., 1., 0., -3., 0., 0., 1.,
        ],
    );
    // View 5 (260..296): a morph target moving every vertex by (0, 0, 2).
    floats(&mut bin, &[0.0, 0.0, 2.0, 0.0, 0.0, 2.0, 0.0, 0.0, 2.0]);
    // View 6 (296..304): an animation's two key times.
    floats(&mut bin, &[0.0, 1.0]);
    // View 7 (304..328): its two translations.
    floats(&mut bin, &[0.0, 0.0, 0.0, 0.0, 9.0, 0.0]);
    std::fs::write(dir.join(format!("{name}.bin")), &bin).unwrap();
    let gltf = format!(
        r#"{{
  "asset": {{"version": "2.0"}},
  "buffers": [{{"uri": "{name}.bin", "byteLength": {len}}}],
  "bufferViews": [
    {{"buffer": 0, "byteOffset": 0, "byteLength": 36}},
    {{"buffer": 0, "byteOffset": 36, "byteLength": 36}},
    {{"buffer": 0, "byteOffset": 72, "byteLength": 12}},
    {{"buffer": 0, "byteOffset": 84, "byteLength": 48}},
    {{"buffer": 0, "byteOffset": 132, "byteLength": 128}},
    {{"buffer": 0, "byteOffset": 260, "byteLength": 36}},
    {{"buffer": 0, "byteOffset": 296, "byteLength": 8}},
    {{"buffer": 0, "byteOffset": 304, "byteLength": 24}}
  ],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}},
    {{"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC3"}},
    {{"bufferView": 2, "componentType": 5121, "count": 3, "type": "VEC4"}},
    {{"bufferView": 3, "componentType": 5126, "count": 3, "type": "VEC4"}},
    {{"bufferView": 4, "componentType": 5126, "count": 2, "type": "MAT4"}},
    {{"bufferView": 5, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 2], "max": [0, 0, 2]}},
    {{"bufferView": 6, "componentType": 5126, "count": 2, "type": "SCALAR", "min": [0], "max": [1]}},
    {{"bufferView": 7, "componentType": 5126, "count": 2, "type": "VEC3"}}
  ],
  {json}
}}"#,
        len = bin.len(),
    );
    let path = dir.join(format!("{name}.gltf"));
    std::fs::write(&path, gltf).unwrap();
    path
}

/// The corners of the description's triangles, and its warnings.
fn corners(path: &Path) -> (Vec<[Vec3; 3]>, Vec<String>) {
    let mut d = formats::load(path)
        .unwrap_or_else(|e| panic!("{e}"))
        .description;
    d.flatten_instances().unwrap();
    let triangles = d
        .triangles
        .iter()
        .map(|t| t.positions.map(|i| d.positions[i as usize]))
        .collect();
    (triangles, d.warnings)
}

fn close(a: Vec3, b: Vec3) -> bool {
    (a - b).abs().max_element() < 1e-5
}

#[test]
fn a_skinned_mesh_is_placed_by_its_joints_in_their_default_pose() {
    // Node 0 holds the skinned mesh under a transform that glTF says to ignore;
    // joint 0 (node 1) stands at z = -5, joint 1 (node 2, its child) 3 along x and
    // 1 up from it, bound 3 along x: so moved by (0, 1, 0) from its bind pose.
    let dir = tempfile::tempdir().unwrap();
    let path = write(
        dir.path(),
        "skinned",
        r#""scene": 0,
  "scenes": [{"nodes": [0, 1]}],
  "nodes": [
    {"mesh": 0, "skin": 0, "translation": [100, 0, 0], "scale": [3, 3, 3]},
    {"translation": [0, 0, -5], "children": [2]},
    {"translation": [3, 1, 0]}
  ],
  "skins": [{"joints": [1, 2], "inverseBindMatrices": 4}],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "JOINTS_0": 2, "WEIGHTS_0": 3}}]}]"#,
    );
    let (triangles, warnings) = corners(&path);
    assert!(warnings.is_empty(), "{warnings:?}");
    let [a, b, c] = triangles[0];
    // Vertices 0 and 1 on joint 0 alone (vertex 1's weight of 2 scaled to 1).
    assert!(close(a, Vec3::new(0.0, 0.0, -5.0)), "{a}");
    assert!(close(b, Vec3::new(1.0, 0.0, -5.0)), "{b}");
    // Vertex 2 half on each: half of joint 1's move up.
    assert!(close(c, Vec3::new(0.0, 1.5, -5.0)), "{c}");
}

#[test]
fn morph_targets_are_blended_by_the_default_weights_of_the_node_else_the_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = |weights: &str| {
        format!(
            r#""meshes": [{{"weights": [{weights}], "primitives": [{{"attributes": {{"POSITION": 0, "NORMAL": 1}}, "targets": [{{"POSITION": 5}}]}}]}}]"#
        )
    };
    let cases = [
        // The mesh's weight: half the target's (0, 0, 2).
        (mesh("0.5"), r#"{"mesh": 0}"#, 1.0),
        // The node's weights replace the mesh's.
        (mesh("0.5"), r#"{"mesh": 0, "weights": [1.0]}"#, 2.0),
        // A weight of 0: the mesh as it is.
        (mesh("0"), r#"{"mesh": 0}"#, 0.0),
    ];
    for (k, (meshes, node, z)) in cases.iter().enumerate() {
        let json =
            format!(r#""scene": 0, "scenes": [{{"nodes": [0]}}], "nodes": [{node}], {meshes}"#);
        let (triangles, warnings) = corners(&write(dir.path(), &format!("m{k}"), &json));
        assert!(warnings.is_empty(), "{warnings:?}");
        let [a, b, c] = triangles[0];
        for (corner, expected) in [(a, [0.0, 0.0]), (b, [1.0, 0.0]), (c, [0.0, 1.0])] {
            let expected = Vec3::new(expected[0], expected[1], *z);
            assert!(close(corner, expected), "case {k}: {corner} for {expected}");
        }
    }
}

#[test]
fn nodes_sharing_a_morphed_mesh_each_pose_it_by_their_own_weights() {
    // Three nodes place one mesh (so as instances of one read mesh): the first two
    // with weights of their own, the third with the mesh's.
    let dir = tempfile::tempdir().unwrap();
    let json = r#""scene": 0, "scenes": [{"nodes": [0, 1, 2]}],
  "nodes": [
    {"mesh": 0, "weights": [1.0]},
    {"mesh": 0, "weights": [0.0], "translation": [10, 0, 0]},
    {"mesh": 0, "translation": [20, 0, 0]}
  ],
  "meshes": [{"weights": [0.5], "primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1}, "targets": [{"POSITION": 5}]}]}]"#;
    let (triangles, warnings) = corners(&write(dir.path(), "shared", json));
    assert!(warnings.is_empty(), "{warnings:?}");
    assert_eq!(triangles.len(), 3);
    for (x, z) in [(0.0, 2.0), (10.0, 0.0), (20.0, 1.0)] {
        let corner = Vec3::new(x, 1.0, z);
        assert!(
            triangles.iter().any(|t| close(t[2], corner)),
            "no triangle with its third corner at {corner}: {triangles:?}"
        );
    }
}

#[test]
fn animations_are_one_warning_naming_the_file_and_the_pose_is_the_default() {
    let dir = tempfile::tempdir().unwrap();
    let path = write(
        dir.path(),
        "animated",
        r#""scene": 0,
  "scenes": [{"nodes": [0]}],
  "nodes": [{"mesh": 0}],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
  "animations": [
    {"channels": [{"sampler": 0, "target": {"node": 0, "path": "translation"}}],
     "samplers": [{"input": 6, "output": 7}]},
    {"channels": [{"sampler": 0, "target": {"node": 0, "path": "translation"}}],
     "samplers": [{"input": 6, "output": 7}]}
  ]"#,
    );
    let (triangles, warnings) = corners(&path);
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(
        warnings[0].starts_with(&path.display().to_string())
            && warnings[0].contains("2 animation(s) not played"),
        "{}",
        warnings[0]
    );
    assert!(close(triangles[0][2], Vec3::new(0.0, 1.0, 0.0)));
}

#[test]
fn a_skin_that_cannot_be_read_is_one_warning_and_the_mesh_stays_at_its_node() {
    // Three joints, two inverse bind matrices; and a second node skinned alike.
    let dir = tempfile::tempdir().unwrap();
    let path = write(
        dir.path(),
        "short",
        r#""scene": 0,
  "scenes": [{"nodes": [0, 1, 2]}],
  "nodes": [
    {"mesh": 0, "skin": 0, "translation": [0, 0, -2]},
    {"mesh": 0, "skin": 0, "translation": [0, 0, -4]},
    {"translation": [0, 7, 0]}
  ],
  "skins": [{"joints": [2, 2, 2], "inverseBindMatrices": 4}],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "JOINTS_0": 2, "WEIGHTS_0": 3}}]}]"#,
    );
    let (triangles, warnings) = corners(&path);
    assert_eq!(warnings.len(), 1, "{warnings:?}");
    assert!(
        warnings[0].contains("2 inverse bind matrices for 3 joints")
            && warnings[0].contains("unskinned"),
        "{}",
        warnings[0]
    );
    let mut zs: Vec<f32> = triangles.iter().map(|t| t[0].z).collect();
    zs.sort_by(f32::total_cmp);
    assert_eq!(zs, [-4.0, -2.0]);
}
