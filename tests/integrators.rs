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

/// An octahedron of "radius" 1 whose vertex normals point out from its centre, as a
/// coarse sphere's do, and, with `occluder`, a small flat triangle hovering 0.05 above
/// the point `(0.8, 0.1, 0.1)` of its face in the positive octant.
fn smooth_octahedron(occluder: bool) -> Scene {
    let mut obj = crate::support::smooth_octahedron_obj();
    if occluder {
        let centre = Vec3::new(0.8, 0.1, 0.1) + Vec3::ONE.normalize() * 0.05;
        for corner in [Vec3::X, Vec3::Y, Vec3::Z] {
            let v = centre + (corner - Vec3::splat(1.0 / 3.0)) * 0.03;
            obj += &format!("v {} {} {}\n", v.x, v.y, v.z);
        }
        obj += "f 7 8 9\n";
    }
    let description = formats::parse_obj(obj.as_bytes(), Path::new("octahedron.obj")).unwrap();
    Scene::build(description, &BvhParams::default())
}

/// The shadow terminator: where a flat triangle of a smooth mesh faces away from a
/// light that its interpolated normal still faces, the shadow ray from the triangle
/// runs into the mesh. A convex surface cannot shadow a point of itself whose normal
/// faces the light, so the octahedron that stands for a sphere must not either: the
/// shadow ray starts from the smooth surface its vertex normals describe. Where the
/// light is well above the triangle, shadow rays still start on it, so the occluder
/// just above the surface (nearer than the smooth surface) still casts its shadow.
/// Under the default rig only: a scene with lights of its own keeps SPEC's rule, every
/// shadow ray an epsilon off the triangle, which shadows the face.
#[test]
fn under_the_rig_a_smooth_mesh_does_not_shadow_itself_where_its_shading_faces_the_light() {
    let p = Vec3::new(0.8, 0.1, 0.1);
    let face = Vec3::ONE.normalize();
    let eye = p + Vec3::new(1.0, -0.3, -0.3).normalize() * 2.0;
    let ray = raytracer::math::Ray::new(eye, (p - eye).normalize());

    let mut scene = smooth_octahedron(false);
    let light = p + Vec3::new(1.0, -0.7, -0.7).normalize() * 10.0;
    // SPEC's shadow ray, off the triangle (full mode drops the lift in a scene with
    // lights of its own): into the mesh, blocked.
    let hit = scene.intersect(&ray).expect("the ray meets the face");
    let spec_hit = raytracer::Hit {
        lift: Vec3::ZERO,
        ..hit
    };
    let (shadow, distance) = spec_hit.spawn_ray_to(light);
    assert!(
        scene.occluded(&shadow, distance),
        "SPEC's shadow ray got out"
    );
    scene.set_lit_by_rig(true);
    let hit = scene.intersect(&ray).expect("the ray meets the face");
    assert!((hit.p - p).length() < 1e-5, "{}", hit.p);
    // Behind the triangle's plane, in front of its shading normal.
    let to_light = (light - hit.p).normalize();
    assert!(hit.n.dot(face) > 0.999 && hit.n.dot(to_light) < -0.1);
    assert!(hit.ns.dot(to_light) > 0.5, "{}", hit.ns.dot(to_light));
    let (shadow, distance) = hit.spawn_ray_to(light);
    assert!(
        !scene.occluded(&shadow, distance),
        "self-shadowed from {shadow:?}"
    );

    let mut scene = smooth_octahedron(true);
    scene.set_lit_by_rig(true);
    let hit = scene.intersect(&ray).expect("the ray passes the occluder");
    assert!((hit.p - p).length() < 1e-5, "{}", hit.p);
    let (shadow, distance) = hit.spawn_ray_to(p + face * 3.0);
    assert!(
        scene.occluded(&shadow, distance),
        "lit through the occluder"
    );
}

/// A square in the plane z = 0 with every vertex normal `normal`, lit by full mode's
/// default rig for `options`.
fn square_under_the_rig(normal: Vec3, options: &RenderOptions) -> Scene {
    let obj = format!(
        "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvn {} {} {}\nf 1//1 2//1 3//1\nf 1//1 3//1 4//1\n",
        normal.x, normal.y, normal.z
    );
    let mut description = formats::parse_obj(obj.as_bytes(), Path::new("square.obj")).unwrap();
    description.add_default_light(options);
    Scene::build(description, &BvhParams::default())
}

/// Under the default rig, a shading normal that faces away from the eye (as
/// interpolated normals do along a low-poly silhouette) is shaded as the normal bent
/// towards the eye until it mirrors the eye 0.01 (in cosine) above the surface:
/// a square whose normals lean 45 degrees away from an eye 60 degrees off its axis
/// looks as one whose normals are that bent normal, worked out here by its
/// definition. Unbent, full mode shaded it about the normal turned round to face the
/// ray, a dark fringe round smooth models.
#[test]
fn under_the_rig_a_shading_normal_facing_away_from_the_eye_is_bent_towards_it() {
    let (s60, c60) = (60f32.to_radians().sin(), 60f32.to_radians().cos());
    let wo = Vec3::new(s60, 0.0, c60);
    let leaning = Vec3::new(-1.0, 0.0, 1.0).normalize();
    let threshold = (0.9 * c60).min(0.01);
    let wanted = Vec3::new(-(1.0 - threshold * threshold).sqrt(), 0.0, threshold);
    let bent = (wo + wanted).normalize();
    let options = RenderOptions {
        width: 8,
        height: 8,
        fov_degrees: 1.0,
        look_from: wo * 5.0,
        look_to: Vec3::ZERO,
        mode: Mode::Full,
        ..RenderOptions::default()
    };
    let mean = |normal: Vec3| {
        let film = render(&square_under_the_rig(normal, &options), &options);
        film.pixels.iter().sum::<Vec3>() / film.pixels.len() as f32
    };
    let (seen, expected) = (mean(leaning), mean(bent));
    assert!(
        (seen - expected).abs().max_element() < 0.01 * expected.max_element(),
        "leaning normals {seen}, bent ones {expected}"
    );
}

/// Full mode traces a pinhole's camera rays in 4x4 packets at any number of samples
/// per pixel, sample by sample: each pixel of the image is bit for bit what
/// [`raytracer::Integrator::pixel`] makes of it ray by ray (the thin sheet's
/// refraction and the box's shadows included), at 1, 2, 4 and 9 samples.
#[test]
fn full_mode_packets_at_any_samples_per_pixel_are_the_pixels_ray_by_ray() {
    use raytracer::Integrator;
    use raytracer::integrators::WhittedIntegrator;
    use raytracer::integrators::aov::PixelAovs;
    use raytracer::sampler::PixelSampler;
    use raytracer::stats::RayCounts;

    let scene = thin_sheet_scene();
    for spp in [1, 2, 4, 9] {
        let options = RenderOptions {
            width: SIZE + 2,
            height: SIZE - 3,
            fov_degrees: 60.0,
            depth: 3,
            mode: Mode::Full,
            samples_per_pixel: spp,
            ..RenderOptions::default()
        };
        options.validate().unwrap();
        let film = render(&scene, &options);
        let integrator = WhittedIntegrator { max_depth: 3 };
        let camera = raytracer::Camera::for_options(&options);
        let sampler = PixelSampler::new(spp, integrator.dimensions());
        let mut lit = 0;
        for row in 0..options.height {
            for column in 0..options.width {
                let single = integrator.pixel(
                    &scene,
                    &camera,
                    &sampler,
                    (column, row, options.width),
                    &mut RayCounts::default(),
                    &mut PixelAovs::none(),
                );
                let packed = film.pixels[(row * options.width + column) as usize];
                assert_eq!(
                    packed.to_array().map(f32::to_bits),
                    single.to_array().map(f32::to_bits),
                    "pixel ({column}, {row}) at {spp} samples"
                );
                lit += usize::from(single != Vec3::ZERO);
            }
        }
        assert!(lit > 200, "{lit} pixels lit");
    }
}
