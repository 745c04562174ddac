//! `raytracer info` and `raytracer render` agree on which triangles are degenerate:
//! the count `SceneSummary` reports is the count `Scene::build` skips and warns about,
//! for the cases where a rule could go either way (repeated indices, collinear
//! corners, and tiny or huge coordinates whose normal underflows or overflows).

use rand::{Rng, SeedableRng};
use raytracer::description::{SceneDescription, TriangleDesc};
use raytracer::math::{Ray, Vec3};
use raytracer::scene::SceneSummary;
use raytracer::{BvhParams, Material, MaterialId, RenderOptions, Scene};

/// A one-material description of the given triangles, each with its own corners.
fn description(triangles: &[[Vec3; 3]]) -> SceneDescription {
    let mut d = SceneDescription::default();
    d.materials.push(Material::fallback());
    for corners in triangles {
        let base = d.positions.len() as u32;
        d.positions.extend_from_slice(corners);
        d.triangles.push(TriangleDesc {
            positions: [base, base + 1, base + 2],
            normals: None,
            material: MaterialId(0),
        });
    }
    d
}

/// The count `raytracer info` prints.
fn info_count(d: &SceneDescription) -> usize {
    SceneSummary::new(d, &RenderOptions::default()).degenerate_triangles
}

/// The count `raytracer render` warns about, 0 without a warning; checked against
/// the primitives the scene kept.
fn render_count(d: &SceneDescription) -> usize {
    let scene = Scene::build(d.clone(), &BvhParams::default());
    let counts: Vec<usize> = scene
        .warnings
        .iter()
        .filter_map(|w| w.strip_prefix("skipped "))
        .map(|rest| {
            let (n, what) = rest.split_once(' ').unwrap();
            assert!(
                what.starts_with("degenerate (zero-area) triangle"),
                "{rest}"
            );
            n.parse().unwrap()
        })
        .collect();
    assert!(counts.len() <= 1, "{:?}", scene.warnings);
    let count = counts.first().copied().unwrap_or(0);
    assert_eq!(scene.prim_count(), d.triangles.len() - count);
    count
}

#[test]
fn info_counts_the_triangles_render_skips() {
    let v = Vec3::new;
    let tiny = 1e-12;
    let mut d = description(&[
        // Kept by every rule.
        [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(0.0, 1.0, 0.0)],
        // Collinear, distinct corners: the cross product is exactly zero.
        [v(0.0, 0.0, 0.0), v(1.0, 1.0, 1.0), v(2.0, 2.0, 2.0)],
        // Tiny: the normal (0, 0, 1e-24) is a direction, but its squared length
        // underflows to zero in f32.
        [v(0.0, 0.0, 5.0), v(tiny, 0.0, 5.0), v(0.0, tiny, 5.0)],
        // Huge: the normal's squared length overflows, the normal does not.
        [v(0.0, 0.0, 0.0), v(1e19, 0.0, 0.0), v(0.0, 1e19, 0.0)],
        // Huger: the normal itself overflows to infinity.
        [v(0.0, 0.0, 0.0), v(1e20, 0.0, 0.0), v(0.0, 1e20, 0.0)],
        // Distinct corners that coincide once stored as a vertex and two edges.
        [v(1e8, 0.0, 0.0), v(1e8 + 1.0, 0.0, 0.0), v(1e8, 1.0, 0.0)],
    ]);
    // A repeated vertex index.
    d.triangles.push(TriangleDesc {
        positions: [0, 0, 1],
        ..d.triangles[0]
    });
    assert_eq!(info_count(&d), render_count(&d));
    assert_eq!(info_count(&d), 4);

    // The tiny triangle is kept because it renders: a ray hits it with a unit normal.
    let scene = Scene::build(d, &BvhParams::default());
    let ray = Ray::new(v(tiny / 4.0, tiny / 4.0, 6.0), -Vec3::Z);
    let hit = scene.intersect(&ray).expect("the tiny triangle is hit");
    assert_eq!(hit.n, Vec3::Z);
}

#[test]
fn info_and_render_agree_at_every_scale() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(17);
    for exponent in (-40..=38).step_by(2) {
        let scale = 10f32.powi(exponent);
        let triangles: Vec<[Vec3; 3]> = (0..200)
            .map(|i| {
                let mut corner = || {
                    Vec3::new(
                        rng.random_range(-1.0..1.0),
                        rng.random_range(-1.0..1.0),
                        rng.random_range(-1.0..1.0),
                    ) * scale
                };
                let (a, b) = (corner(), corner());
                // Every third triangle collinear (up to rounding), every fifth with
                // a repeated corner.
                let c = match i {
                    i if i % 3 == 0 => a + (b - a) * rng.random_range(-2.0..2.0),
                    i if i % 5 == 0 => b,
                    _ => corner(),
                };
                [a, b, c]
            })
            .collect();
        let d = description(&triangles);
        assert_eq!(info_count(&d), render_count(&d), "scale {scale:e}");
    }
}
