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

#[test]
fn copies_of_a_triangle_are_rendered_once() {
    let v = Vec3::new;
    let corners = [v(0.0, 0.0, -2.0), v(1.0, 0.0, -2.0), v(0.0, 1.0, -2.0)];
    let mut d = description(&[corners, corners]);
    d.materials.push(Material::named("other"));
    // 200,000 copies: by index, and by value (corners of their own).
    let copy = d.triangles[0];
    d.triangles.extend(std::iter::repeat_n(copy, 199_998));
    // The same corners with another material, and one corner a float step away:
    // not copies.
    d.triangles.push(TriangleDesc {
        material: MaterialId(1),
        ..copy
    });
    let base = d.positions.len() as u32;
    d.positions
        .extend([corners[0], corners[1], v(0.0, 1.0f32.next_up(), -2.0)]);
    d.triangles.push(TriangleDesc {
        positions: [base, base + 1, base + 2],
        ..copy
    });
    let scene = Scene::build(d, &BvhParams::default());
    assert_eq!(scene.prim_count(), 3);
    assert!(
        scene
            .warnings
            .iter()
            .any(|w| w.starts_with("skipped 199999 duplicate shapes")),
        "{:?}",
        scene.warnings
    );
    scene.validate().unwrap();
    let hit = scene
        .intersect(&Ray::new(v(0.25, 0.25, 0.0), -Vec3::Z))
        .expect("the triangle is hit");
    assert_eq!(hit.t, 2.0);
}

#[test]
fn scenes_without_copies_keep_every_shape() {
    // Boxes (so centroids) that coincide, more than a leaf holds, without copies:
    // triangles from one corner of a square to points on its far sides.
    let v = Vec3::new;
    let triangles: Vec<[Vec3; 3]> = (1..=20)
        .map(|k| {
            let f = k as f32 / 21.0;
            [v(0.0, 0.0, -2.0), v(1.0, f, -2.0), v(1.0 - f, 1.0, -2.0)]
        })
        .collect();
    let d = description(&triangles);
    let scene = Scene::build(d, &BvhParams::default());
    assert_eq!(scene.prim_count(), 20);
    assert!(
        !scene.warnings.iter().any(|w| w.contains("duplicate")),
        "{:?}",
        scene.warnings
    );
}
