//! Replays the reference geometry vectors (`tests/data/reference/geometry/*.txt`):
//! ray/sphere and ray/triangle hits (distance, point, normal facing the ray), mirror
//! reflection and refraction (with total internal reflection).
//!
//! The vectors were checked at 1e-9 in double precision; the renderer computes in
//! `f32`, whose unit roundoff is 6e-8, and a hit goes through about ten dependent
//! roundings on values up to ~5, so we allow 1e-4 relative to max(1, |value|).

use crate::support;

use raytracer::description::{SceneDescription, SphereDesc, TriangleDesc};
use raytracer::math::{Ray, Vec3, reflect, refract};
use raytracer::{BvhParams, MaterialId, Scene};

const TOLERANCE: f32 = 1e-4;

fn records(name: &str) -> Vec<Vec<f64>> {
    let path = support::reference_dir().join("geometry").join(name);
    let text = std::fs::read_to_string(&path).unwrap();
    let mut lines = text.lines().filter(|l| !l.trim().is_empty());
    let count: usize = lines.next().unwrap().trim().parse().unwrap();
    let records: Vec<Vec<f64>> = lines
        .map(|l| l.split_whitespace().map(|t| t.parse().unwrap()).collect())
        .collect();
    assert_eq!(records.len(), count, "{name}: record count");
    records
}

fn v(values: &[f64]) -> Vec3 {
    Vec3::new(values[0] as f32, values[1] as f32, values[2] as f32)
}

#[track_caller]
fn assert_close(what: &str, record: usize, got: Vec3, expected: Vec3) {
    let scale = expected.abs().max_element().max(1.0);
    assert!(
        (got - expected).abs().max_element() <= TOLERANCE * scale,
        "record {record}: {what}: got {got}, expected {expected}, difference {}",
        (got - expected).abs().max_element()
    );
}

/// Checks a hit record's tail `[t]` or `[t, px, py, pz, nx, ny, nz]` against `scene`.
fn check_hit(scene: &Scene, ray: &Ray, expected: &[f64], record: usize) -> bool {
    let hit = scene.intersect(ray);
    if expected[0] == -1.0 {
        assert!(
            hit.is_none(),
            "record {record}: expected a miss, got {hit:?}"
        );
        return false;
    }
    let hit = hit.unwrap_or_else(|| panic!("record {record}: expected a hit at {}", expected[0]));
    let t = expected[0] as f32;
    assert!(
        (hit.t - t).abs() <= TOLERANCE * t.max(1.0),
        "record {record}: t = {}, expected {t}",
        hit.t
    );
    assert_close("point", record, hit.p, v(&expected[1..4]));
    assert_close("normal", record, hit.n, v(&expected[4..7]));
    true
}

#[test]
fn ray_sphere_records() {
    let mut hits = 0;
    for (i, r) in records("sphere.txt").iter().enumerate() {
        let mut description = SceneDescription::default();
        description.spheres.push(SphereDesc {
            center: v(&r[6..9]),
            radius: r[9] as f32,
            material: MaterialId(0),
        });
        let scene = Scene::build(description, &BvhParams::default());
        let ray = Ray::new(v(&r[0..3]), v(&r[3..6]));
        hits += check_hit(&scene, &ray, &r[10..], i) as usize;
    }
    assert!(hits > 20, "the file exercises hits ({hits})");
}

#[test]
fn ray_triangle_records() {
    let mut hits = 0;
    for (i, r) in records("triangle.txt").iter().enumerate() {
        let description = SceneDescription {
            positions: vec![v(&r[6..9]), v(&r[9..12]), v(&r[12..15])],
            triangles: vec![TriangleDesc {
                positions: [0, 1, 2],
                material: MaterialId(0),
            }],
            ..SceneDescription::default()
        };
        let scene = Scene::build(description, &BvhParams::default());
        let ray = Ray::new(v(&r[0..3]), v(&r[3..6]));
        hits += check_hit(&scene, &ray, &r[15..], i) as usize;
    }
    assert!(hits > 20, "the file exercises hits ({hits})");
}

#[test]
fn reflect_records() {
    for (i, r) in records("reflect.txt").iter().enumerate() {
        assert_close(
            "reflection",
            i,
            reflect(v(&r[0..3]), v(&r[3..6])),
            v(&r[6..9]),
        );
    }
}

#[test]
fn refract_records() {
    let mut total_internal = 0;
    for (i, r) in records("refract.txt").iter().enumerate() {
        let got = refract(v(&r[0..3]), v(&r[3..6]), 1.1);
        if r[6] == 0.0 {
            assert_eq!(got, None, "record {i}: expected total internal reflection");
            total_internal += 1;
        } else {
            let got =
                got.unwrap_or_else(|| panic!("record {i}: unexpected total internal reflection"));
            assert_close("refraction", i, got, v(&r[7..10]));
        }
    }
    assert!(
        total_internal > 0,
        "the file exercises total internal reflection"
    );
}
