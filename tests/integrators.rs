//! What the integrators compute, on small scenes made for one rule each.

use std::path::Path;

use raytracer::math::Vec3;
use raytracer::{BvhParams, Film, Mode, RenderOptions, Scene, formats, render};

/// `tests/data/thin-sheet`: a refractive quad (`al 0 0 1`, `Ni 1.5`) at z = -1 in
/// front of an opaque diffuse box (front face at z = -2, `Ka 0.1`, `Kd 0.8 0.5 0.2`)
/// with a white point light at (0, 0, -1.5), between the two.
fn thin_sheet_scene() -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/thin-sheet/scene.obj");
    Scene::build(formats::load_obj(&path).unwrap(), &BvhParams::default())
}

/// An odd size, so that the centre pixel's ray is exactly the view axis -z.
const SIZE: u32 = 33;
const CENTRE: usize = (SIZE / 2 * SIZE + SIZE / 2) as usize;

fn render_thin_sheet(scene: &Scene, depth: u32) -> Film {
    let options = RenderOptions {
        width: SIZE,
        height: SIZE,
        fov_degrees: 60.0,
        depth,
        mode: Mode::Full,
        ..RenderOptions::default()
    };
    options.validate().unwrap();
    render(scene, &options)
}

#[test]
fn a_ray_that_crossed_a_thin_sheet_stops_at_the_opaque_box_behind_it() {
    let scene = thin_sheet_scene();
    // The sheet has no terms of its own: what the centre pixel shows came through it.
    assert_eq!(render_thin_sheet(&scene, 1).pixels[CENTRE], Vec3::ZERO);

    // The centre ray meets the sheet head-on, goes straight on (inside glass by
    // SPEC's rule) and hits the box's front face at (0, 0, -2), lit head-on from
    // (0, 0, -1.5): SPEC's value there is Ka + Kd * I * (n . l) = 0.1 + Kd. A box
    // that kept refracting would let the ray on to the back face and add its Ka too.
    let expected = Vec3::new(0.9, 0.6, 0.3);
    let got = render_thin_sheet(&scene, 8).pixels[CENTRE];
    assert!(
        (got - expected).abs().max_element() < 1e-5,
        "centre pixel {got}, expected the box's own shading {expected}"
    );
}

#[test]
fn behind_a_thin_sheet_recursion_beyond_the_box_adds_nothing() {
    // Depth 2 stops every ray at the box after it crossed the sheet; with more depth
    // the box must not pass rays on either, so the images are the same, including
    // the pixels whose rays the sheet bent.
    let scene = thin_sheet_scene();
    let two = render_thin_sheet(&scene, 2);
    let bent_onto_the_box = two
        .pixels
        .iter()
        .enumerate()
        .filter(|&(i, v)| i != CENTRE && *v != Vec3::ZERO)
        .count();
    assert!(
        bent_onto_the_box > 50,
        "only {bent_onto_the_box} pixels see the box"
    );
    for depth in [3, 8] {
        assert_eq!(render_thin_sheet(&scene, depth), two, "depth {depth}");
    }
}
