//! Right shapes from OBJ faces: concave and non-planar polygons keep their outline
//! (ear clipping in the best-fit plane; convex ones keep SPEC's fan), and smoothing
//! groups give faces without `vn` smooth vertex normals.

use std::fmt::Write;
use std::path::Path;

use raytracer::formats::parse_obj;
use raytracer::math::Vec3;
use raytracer::{BvhParams, RenderOptions, Scene, SceneDescription, render};

fn parse(text: &str) -> SceneDescription {
    parse_obj(text.as_bytes(), Path::new("shape.obj")).unwrap_or_else(|e| panic!("{e}"))
}

/// A flat ring at z = -3 (outer radius 1, inner 0.5, `segments` each way) written as
/// one face: round the outside, in along a cut, round the inside the other way, out
/// along the same cut. With a light at the eye.
fn ring_obj(segments: usize) -> String {
    let mut text = String::from("P 0 0 0 1 1 1\n");
    let at = |r: f32, k: usize| {
        let a = std::f32::consts::TAU * (k % segments) as f32 / segments as f32;
        (r * a.cos(), r * a.sin())
    };
    for k in 0..=segments {
        let (x, y) = at(1.0, k);
        writeln!(text, "v {x} {y} -3").unwrap();
    }
    for k in 0..=segments {
        let (x, y) = at(0.5, segments - k);
        writeln!(text, "v {x} {y} -3").unwrap();
    }
    text.push('f');
    for i in 1..=2 * (segments + 1) {
        write!(text, " {i}").unwrap();
    }
    text.push('\n');
    text
}

/// Renders `description` from the origin looking down -z at 64x64, 45 degrees.
fn render_lit(description: SceneDescription) -> Vec<Vec3> {
    let scene = Scene::build(description, &BvhParams::default());
    let options = RenderOptions {
        width: 64,
        height: 64,
        fov_degrees: 45.0,
        ..RenderOptions::default()
    };
    render(&scene, &options).pixels
}

#[test]
fn a_ring_keeps_its_hole() {
    let pixels = render_lit(parse(&ring_obj(48)));
    // The hole has radius 0.5 at distance 3: tan = 0.167, against tan(22.5°) = 0.414
    // for half the image, so 13 pixels from the centre. Count lit pixels within 10.
    let (mut in_hole, mut on_ring) = (0, 0);
    for y in 0..64 {
        for x in 0..64 {
            let (dx, dy) = (x as f32 + 0.5 - 32.0, y as f32 + 0.5 - 32.0);
            let r = (dx * dx + dy * dy).sqrt();
            let lit = pixels[y * 64 + x].max_element() > 0.0;
            if r < 10.0 && lit {
                in_hole += 1;
            }
            if (16.0..24.0).contains(&r) && lit {
                on_ring += 1;
            }
        }
    }
    assert_eq!(in_hole, 0, "the hole is filled: the ring became a disc");
    // The ring itself is all there: 16 <= r < 24 is about 1000 pixels.
    assert!(on_ring > 900, "{on_ring}");
}

#[test]
fn convex_polygons_keep_the_fan_and_concave_ones_keep_their_outline() {
    // A square: the fan (0, i, i+1), as SPEC.md says.
    let d = parse("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n");
    let fan: Vec<[u32; 3]> = d.triangles.iter().map(|t| t.positions).collect();
    assert_eq!(fan, [[0, 1, 2], [0, 2, 3]]);
    // An arrow head, concave at corner 3, tilted out of every axis plane: the fan from
    // corner 1 would cover the notch; the ear cut does not.
    let d =
        parse("v 0 0.5 0.5\nv 1 0 0\nv 0.5 0.5 0.25\nv 1 1 0\nvn 0 0 1\nf 1//1 2//1 3//1 4//1\n");
    assert_eq!(d.triangles.len(), 2);
    for (i, t) in d.triangles.iter().enumerate() {
        // Corner 3 (index 2), the notch, is in both triangles: each triangle is an ear
        // on one side of it.
        assert!(t.positions.contains(&2), "{:?}", t.positions);
        assert_eq!(d.normals_of(i), Some([0, 0, 0]));
    }
}

#[test]
fn a_face_of_200000_corners_is_cut_into_triangles_that_cover_it_once() {
    // How the work grows with the corners is tested in `formats::polygon` by counting
    // steps; here, that such a face reads and covers its area exactly once.
    let n = 200_000;
    let mut text = String::with_capacity(n * 40);
    for k in 0..n {
        let a = std::f64::consts::TAU * k as f64 / n as f64;
        let r = if k % 2 == 0 { 1.0 } else { 0.9 };
        writeln!(text, "v {:.6} {:.6} 0", r * a.cos(), r * a.sin()).unwrap();
    }
    text.push('f');
    for i in 1..=n {
        write!(text, " {i}").unwrap();
    }
    text.push('\n');
    let d = parse(&text);
    assert_eq!(d.triangles.len(), n - 2);
    // The triangles cover the star once: their areas add up to its area, and none
    // folds over (beyond rounding), as a wrong cut would.
    let mut total = 0.0f64;
    for t in &d.triangles {
        let [a, b, c] = t.positions.map(|i| d.positions[i as usize].as_dvec3());
        let area = (b - a).cross(c - a).z;
        assert!(area > -1e-8, "{area}");
        total += area;
    }
    let star: f64 = (0..n)
        .map(|i| {
            let (a, b) = (
                d.positions[i].as_dvec3(),
                d.positions[(i + 1) % n].as_dvec3(),
            );
            a.cross(b).z
        })
        .sum();
    assert!((total - star).abs() < 1e-6 * star, "{total} vs {star}");
}

/// Two faces meeting at a ridge along x (the edge from (0,0,0) to (1,0,0)), each
/// tilted 45 degrees, written in `group` (with their own copies of the ridge's
/// corners for the second face, as some exporters write them).
fn ridge(group: &str) -> String {
    format!(
        "v 0 0 0\nv 1 0 0\nv 1 1 1\nv 0 1 1\nv 0 0 0\nv 1 0 0\nv 1 -1 1\nv 0 -1 1\n\
         {group}\nf 1 2 3 4\nf 6 5 8 7\n"
    )
}

#[test]
fn smoothing_groups_average_the_normals_of_faces_sharing_a_position() {
    let d = parse(&ridge("s 1"));
    assert_eq!(d.triangles.len(), 4);
    let normal_at = |triangle: usize, position: u32| {
        let t = &d.triangles[triangle];
        let corner = t.positions.iter().position(|&p| p == position).unwrap();
        d.normals[d.normals_of(triangle).expect("smoothed")[corner] as usize]
    };
    // On the ridge: the mean of the two faces' normals, (0,-1,1) and (0,1,1)
    // normalized, is +z; the same vector for both faces, though they have their own
    // copies of the corner.
    for (triangle, position) in [(0, 0), (2, 4)] {
        let n = normal_at(triangle, position);
        assert!((n - Vec3::Z).length() < 1e-6, "{n}");
    }
    // Away from the ridge, each face's own normal.
    let n = normal_at(0, 2);
    assert!(
        (n - Vec3::new(0.0, -1.0, 1.0).normalize()).length() < 1e-6,
        "{n}"
    );
}

#[test]
fn faces_outside_a_group_stay_faceted_and_groups_do_not_mix() {
    for off in ["s off", "s 0", "# no group"] {
        let d = parse(&ridge(off));
        assert!(d.triangle_normals.is_empty(), "{off}");
        assert!(d.normals.is_empty());
    }
    // Each face in its own group: each keeps its own normal at the ridge.
    let d = parse(
        "v 0 0 0\nv 1 0 0\nv 1 1 1\nv 0 1 1\nv 1 -1 1\nv 0 -1 1\n\
         s 1\nf 1 2 3 4\ns 2\nf 2 1 6 5\n",
    );
    let n = d.normals[d.normals_of(0).unwrap()[0] as usize];
    assert!(
        (n - Vec3::new(0.0, -1.0, 1.0).normalize()).length() < 1e-6,
        "{n}"
    );
}

#[test]
fn faces_with_their_own_normals_keep_them_in_a_group() {
    let d = parse(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvn 1 0 0\n\
         s 1\nf 1//1 2//1 3//1\nf 1 2 4\n",
    );
    assert_eq!(d.normals_of(0), Some([0, 0, 0]));
    assert_eq!(d.normals[0], Vec3::X);
    // The second face gets its own: only faces without `vn` are averaged.
    let ids = d.normals_of(1).unwrap();
    assert!(ids.iter().all(|&i| i >= 1));
    let n = d.normals[ids[0] as usize];
    assert!((n - Vec3::NEG_Y).length() < 1e-6, "{n}");
}

#[test]
fn a_group_set_in_an_earlier_chunk_holds_in_later_ones() {
    // Over a megabyte of vertices between `s 1` and the faces: several chunks.
    let ridge = ridge("");
    let (vertices, faces) = ridge.split_at(ridge.find('f').unwrap());
    let mut text = format!("{vertices}s 1\n");
    for _ in 0..60_000 {
        text.push_str("v 0.000000 0.000000 0.000000\n");
    }
    text.push_str(faces);
    let d = parse(&text);
    let smoothed = d.triangle_normals.iter().filter(|n| n.is_some()).count();
    assert_eq!(smoothed, 4);
}

#[test]
fn a_textured_concave_polygon_keeps_each_corner_s_texture_coordinate() {
    // An L-shaped hexagon, concave at corner 4, whose `vt` indices are its `v` indices
    // plus 10: after ear clipping, every triangle's texture coordinates must still be
    // those of its own corners.
    let dir = tempfile::tempdir().unwrap();
    let file = std::fs::File::create(dir.path().join("t.png")).unwrap();
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), 1, 1);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder
        .write_header()
        .unwrap()
        .write_image_data(&[200, 100, 50])
        .unwrap();
    std::fs::write(
        dir.path().join("m.mtl"),
        "newmtl m\nKd 1 1 1\nmap_Kd t.png\n",
    )
    .unwrap();
    let mut obj = String::from("mtllib m.mtl\nusemtl m\n");
    for _ in 0..10 {
        obj += "vt 0 0\n";
    }
    for (x, y) in [(0, 0), (2, 0), (2, 1), (1, 1), (1, 2), (0, 2)] {
        writeln!(obj, "v {x} {y} 0\nvt {x} {y}").unwrap();
    }
    obj += "f 1/11 2/12 3/13 4/14 5/15 6/16\n";
    let path = dir.path().join("l.obj");
    std::fs::write(&path, &obj).unwrap();
    let d = raytracer::formats::load_obj(&path).unwrap();
    assert_eq!(d.triangles.len(), 4);
    assert_eq!(d.triangle_texcoords.len(), 4);
    for (t, texcoords) in d.triangles.iter().zip(&d.triangle_texcoords) {
        assert_eq!(texcoords.unwrap(), t.positions.map(|p| p + 10), "{t:?}");
    }
    // The polygon was re-cut (its triangles are not the fan the reader first wrote),
    // so the texture coordinates had to follow the new triangles.
    let fan_from_0 = [[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 5]];
    assert_ne!(
        d.triangles.iter().map(|t| t.positions).collect::<Vec<_>>(),
        fan_from_0
    );
}
