//! The OBJ/MTL reader: counts and values of the `box` scene, negative indices,
//! polygons, every face form, and every error with its exact message.

use crate::support;

use std::path::Path;

use raytracer::SceneDescription;
use raytracer::formats::{self, SceneError, parse_obj};
use raytracer::math::Vec3;

fn parse(text: &str) -> Result<SceneDescription, SceneError> {
    parse_obj(text.as_bytes(), Path::new("scene.obj"))
}

fn error(text: &str) -> String {
    match parse(text) {
        Ok(_) => panic!("{text:?} parsed without error"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn box_scene_counts_and_values() {
    let path = support::reference_dir().join("scenes/box/cube.obj");
    let d = formats::load_obj(&path).unwrap();
    assert_eq!(d.positions.len(), 24);
    assert_eq!(d.normals.len(), 9);
    // 10 quads-as-triangle-pairs: 10 `f` lines of 3 vertices each.
    assert_eq!(d.triangles.len(), 10);
    assert_eq!(d.spheres.len(), 2);
    assert_eq!(d.lights.len(), 2);
    assert_eq!(d.materials.len(), 9);
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    // Materials keep file order; spheres use the material current at their line.
    let names: Vec<&str> = d.materials.iter().map(|m| m.name.as_str()).collect();
    assert_eq!(&names[..3], ["leftSphere", "rightSphere", "floor"]);
    assert_eq!(d.spheres[0].center, Vec3::new(-0.4, 0.3, -0.4));
    assert_eq!(d.spheres[0].radius, 0.3);
    assert_eq!(
        d.materials[d.spheres[1].material.0 as usize].name,
        "rightSphere"
    );
    let right = &d.materials[1];
    assert_eq!(
        (right.ior, right.opacity, right.shininess),
        (1.8, 0.5, 1024.0)
    );
    assert_eq!(right.albedo, [0.0, 0.3, 0.7]);
    let floor = &d.materials[2];
    assert_eq!(floor.diffuse, Vec3::new(0.725, 0.91, 0.88));
    assert_eq!(floor.specular, Vec3::splat(1.5));
    assert_eq!(d.lights[0].position, Vec3::new(0.0, 1.5899, 0.0));
    assert_eq!(d.lights[1].intensity, Vec3::splat(0.5));
    // `f -4//-1 -3//-1 -2//-1` after the floor's 4 vertices and 1 normal.
    assert_eq!(d.triangles[0].positions, [0, 1, 2]);
    assert_eq!(d.normals_of(0), Some([0, 0, 0]));
    assert_eq!(
        d.materials[d.triangles[0].material.0 as usize].name,
        "floor"
    );
}

#[test]
fn every_face_form_and_polygon_fans() {
    let d = parse(
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0.5 2 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\n\
         f 1 2 3\nf 1/1 2/2 3/3\nf 1//1 2//1 3//1\nf 1/1/1 2/2/1 3/3/1\nf 1 2 3 4 5\n",
    )
    .unwrap();
    assert_eq!(d.triangles.len(), 4 + 3);
    assert_eq!(d.normals_of(0), None);
    assert_eq!(d.normals_of(1), None);
    assert_eq!(d.normals_of(2), Some([0, 0, 0]));
    assert_eq!(d.normals_of(3), Some([0, 0, 0]));
    let fan: Vec<[u32; 3]> = d.triangles[4..].iter().map(|t| t.positions).collect();
    assert_eq!(fan, [[0, 1, 2], [0, 2, 3], [0, 3, 4]]);
    // Normal indices are kept in step with the triangles when the file has normals,
    // and not at all when it has none (16 bytes a triangle for a scan, not 32).
    assert_eq!(d.triangle_normals.len(), d.triangles.len());
    let bare = parse("v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\n").unwrap();
    assert!(bare.triangle_normals.is_empty());
    assert_eq!(
        std::mem::size_of::<raytracer::description::TriangleDesc>(),
        16
    );
}

#[test]
fn negative_indices_count_back_from_the_latest_element() {
    let d = parse("v 0 0 0\nv 1 0 0\nv 1 1 0\nf -3 -2 -1\nv 5 5 5\nf -4 -1 -2\nvn 0 1 0\nf 1//-1 2//1 3//-1\n")
        .unwrap();
    assert_eq!(d.triangles[0].positions, [0, 1, 2]);
    assert_eq!(d.triangles[1].positions, [0, 3, 2]);
    assert_eq!(d.normals_of(2), Some([0, 0, 0]));
}

#[test]
fn whitespace_crlf_tabs_comments_and_ignored_statements() {
    let d = parse(
        "# comment\r\n\r\ng group\r\no object\r\ns 1\r\nv\t0  0 0\r\nv 1\t0\t0 # trailing\r\n  v 0 1 0\r\nf 1 2 3\r\nl 1 2\r\n",
    )
    .unwrap();
    assert_eq!(d.positions.len(), 3);
    assert_eq!(d.positions[1], Vec3::X);
    assert_eq!(d.triangles.len(), 1);
}

#[test]
fn faces_without_a_known_material_get_the_default_with_one_warning() {
    let shapes = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 3\nS 0 0 0 1\n";
    // A file that names no material at all (most scans and robot meshes): the
    // default material, as meant, without a warning.
    let d = parse(shapes).unwrap();
    assert_eq!(d.materials.len(), 1);
    assert_eq!(d.materials[0].name, "default");
    assert!(d.warnings.is_empty(), "{:?}", d.warnings);
    // One that names one later: the shapes before it were likely meant to have one.
    let d = parse(&format!("{shapes}usemtl later\nf 1 2 3\n")).unwrap();
    assert_eq!(d.materials[0].name, "default");
    assert_eq!(
        d.warnings,
        [
            "scene.obj:7: unknown material 'later'; using the default material",
            "scene.obj:4: shapes before any 'usemtl' get the default material"
        ]
    );
    let d = parse("v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl missing\nf 1 2 3\n").unwrap();
    assert_eq!(
        d.warnings,
        ["scene.obj:4: unknown material 'missing'; using the default material"]
    );
    assert_eq!(d.triangles[0].material.0, 0);
}

#[test]
fn spheres_and_lights_keep_file_order() {
    let d = parse("S 1 2 3 4\nP 0 1 0 2 2 2\nS 5 6 7 0.5\nP 9 9 9 0.1 0.2 0.3\n").unwrap();
    assert_eq!(d.spheres.len(), 2);
    assert_eq!(d.spheres[1].center, Vec3::new(5.0, 6.0, 7.0));
    assert_eq!(d.lights[0].intensity, Vec3::splat(2.0));
    assert_eq!(d.lights[1].position, Vec3::splat(9.0));
}

#[test]
fn malformed_lines_name_file_line_and_problem() {
    let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    let cases = [
        ("v 1 2\n", "scene.obj:1: 'v' needs 3 values, found 2"),
        ("v 1 x 3\n", "scene.obj:1: invalid number 'x'"),
        ("S 1 inf 3 1\n", "scene.obj:1: non-finite value 'inf'"),
        ("vt\n", "scene.obj:1: 'vt' needs 1 value, found 0"),
        (
            &format!("{tri}f 1 9\n"),
            "scene.obj:4: face index 9 out of range (3 vertices defined)",
        ),
        (
            "s on\n",
            "scene.obj:1: smoothing group 'on' is not 'off' or a whole number",
        ),
        (
            &format!("{tri}f 1 2 0\n"),
            "scene.obj:4: face index 0 is invalid (indices start at 1)",
        ),
        (
            &format!("{tri}\n\nf 1 2 9\n"),
            "scene.obj:6: face index 9 out of range (3 vertices defined)",
        ),
        (
            &format!("{tri}f 1 2 -4\n"),
            "scene.obj:4: face index -4 out of range (3 vertices defined)",
        ),
        (
            &format!("{tri}f 1/1 2 3\n"),
            "scene.obj:4: texture coordinate index 1 out of range (0 texture coordinates defined)",
        ),
        (
            &format!("{tri}f 1//2 2 3\n"),
            "scene.obj:4: normal index 2 out of range (0 normals defined)",
        ),
        (
            &format!("{tri}f 1/x 2 3\n"),
            "scene.obj:4: malformed face vertex 'x'",
        ),
        (
            &format!("{tri}f 1/1/1/1 2 3\n"),
            "scene.obj:4: malformed face vertex '1/1/1/1'",
        ),
        (
            &format!("{tri}f 1/ 2 3\n"),
            "scene.obj:4: malformed face vertex '1/'",
        ),
        ("S 0 0 0 -1\n", "scene.obj:1: sphere radius -1 is negative"),
        ("S 0 0 0\n", "scene.obj:1: 'S' needs 4 values, found 3"),
        ("P 0 0 0 1 1\n", "scene.obj:1: 'P' needs 6 values, found 5"),
        ("mtllib\n", "scene.obj:1: 'mtllib' needs a name"),
    ];
    for (text, expected) in cases {
        assert_eq!(error(text), expected, "for input {text:?}");
    }
}

#[test]
fn missing_files_and_mtl_errors_name_their_path() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nope.obj");
    let message = formats::load_obj(&missing).unwrap_err().to_string();
    assert!(
        message.starts_with(&format!("{}: ", missing.display())),
        "{message}"
    );

    // A missing library is a warning (tests/forgiving.rs); one that cannot be read is
    // an error.
    let obj = dir.path().join("scene.obj");
    std::fs::create_dir(dir.path().join("folder.mtl")).unwrap();
    std::fs::write(&obj, "mtllib folder.mtl\n").unwrap();
    let message = formats::load_obj(&obj).unwrap_err().to_string();
    assert_eq!(
        message,
        format!(
            "{}:1: cannot read material library {}: is a directory",
            obj.display(),
            dir.path().join("folder.mtl").display()
        )
    );

    std::fs::write(dir.path().join("bad.mtl"), "newmtl a\nKd 1 1\n").unwrap();
    std::fs::write(&obj, "mtllib bad.mtl\n").unwrap();
    let message = formats::load_obj(&obj).unwrap_err().to_string();
    assert_eq!(
        message,
        format!(
            "{}:2: 'Kd' needs 3 values, found 2",
            dir.path().join("bad.mtl").display()
        )
    );

    let message = formats::load_obj(dir.path()).unwrap_err().to_string();
    assert!(
        message.starts_with(&format!("{}: ", dir.path().display())),
        "{message}"
    );
}

#[test]
fn an_mtllib_name_with_spaces_is_one_file_when_that_file_exists() {
    // Onshape writes `mtllib Part Studio 1.mtl` (Genesis's wheel.obj and
    // cross_cutter.obj); Assimp and Blender read the rest of the line as one name.
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("Part Studio 1.mtl"),
        "newmtl red\nKd 1 0 0\n",
    )
    .unwrap();
    let obj = dir.path().join("scene.obj");
    let triangle = "v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n";
    std::fs::write(&obj, format!("mtllib Part Studio 1.mtl\n{triangle}")).unwrap();
    let scene = formats::load_obj(&obj).unwrap();
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let material = &scene.materials[scene.triangles[0].material.0 as usize];
    assert_eq!((material.name.as_str(), material.diffuse), ("red", Vec3::X));

    // Names split at spaces still name several files: the one found is read, the
    // one missing warned about.
    std::fs::write(dir.path().join("a.mtl"), "newmtl red\nKd 0 1 0\n").unwrap();
    std::fs::write(&obj, format!("mtllib a.mtl b.mtl\n{triangle}")).unwrap();
    let scene = formats::load_obj(&obj).unwrap();
    let material = &scene.materials[scene.triangles[0].material.0 as usize];
    assert_eq!(material.diffuse, Vec3::Y);
    let b = dir.path().join("b.mtl");
    assert_eq!(
        scene.warnings,
        [format!(
            "{}:1: material library {} not found; its materials get the default material",
            obj.display(),
            b.display()
        )]
    );

    // A name with spaces found neither whole nor in parts is one warning, not one
    // per word.
    std::fs::write(&obj, format!("mtllib Part Studio 2.mtl\n{triangle}")).unwrap();
    let scene = formats::load_obj(&obj).unwrap();
    assert_eq!(
        scene.warnings,
        [format!(
            "{}:1: material library {} not found; its materials get the default material",
            obj.display(),
            dir.path().join("Part Studio 2.mtl").display()
        )]
    );
}
