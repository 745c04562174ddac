//! Renders every case of `tests/data/reference/cases.toml` and compares it with the
//! expected image: a case passes when at least 99% of pixels lie within Euclidean
//! RGB distance 2. Each case's similarity is printed; a failing case leaves its
//! render and a difference image under `target/reference-failures/`.

use crate::support;

use std::path::Path;

use raytracer::math::Vec3;
use raytracer::{BvhParams, Image, Mode, RenderOptions, Scene, formats, render};

const PASS_FRACTION: f64 = 0.99;
const MAX_DISTANCE: f64 = 2.0;

fn render_case(dir: &Path, case: &support::ReferenceCase) -> Image {
    let mode = match case.mode.as_str() {
        "depth" => Mode::Depth,
        "normal" => Mode::Normal,
        "full" => Mode::Full,
        other => panic!("unknown mode {other}"),
    };
    let options = RenderOptions {
        width: case.width,
        height: case.height,
        fov_degrees: case.fov_degrees,
        look_from: Vec3::from(case.look_from),
        look_to: Vec3::from(case.look_to),
        up: Vec3::Y,
        depth: case.depth,
        mode,
        samples_per_pixel: 1,
        ..RenderOptions::default()
    };
    options.validate().unwrap();
    let description = formats::load_obj(&dir.join(&case.scene)).unwrap();
    let scene = Scene::build(description, &BvhParams::default());
    render(&scene, &options).to_image(mode)
}

/// Fraction of pixels within `MAX_DISTANCE`, and a difference image (distance x 10).
fn compare(got: &Image, expected: &[u8]) -> (f64, Image) {
    let mut close = 0usize;
    let mut diff = Vec::with_capacity(got.rgb.len());
    for (a, b) in got.rgb.chunks(3).zip(expected.chunks(3)) {
        let d2: f64 = a
            .iter()
            .zip(b)
            .map(|(&x, &y)| (x as f64 - y as f64).powi(2))
            .sum();
        let d = d2.sqrt();
        if d <= MAX_DISTANCE {
            close += 1;
        }
        let shade = (d * 10.0).min(255.0) as u8;
        diff.extend([shade, shade, shade]);
    }
    let fraction = close as f64 / (got.width as f64 * got.height as f64);
    let image = Image {
        width: got.width,
        height: got.height,
        rgb: diff,
    };
    (fraction, image)
}

#[test]
fn every_reference_case_matches_its_expected_image() {
    let dir = support::reference_dir();
    let cases = support::reference_cases();
    assert_eq!(cases.len(), 20, "the suite has 20 cases");
    let out_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/reference-failures");
    let mut failures = Vec::new();
    for case in &cases {
        let got = render_case(&dir, case);
        let (width, height, expected) = support::read_png(&dir.join(&case.expected));
        assert_eq!(
            (got.width, got.height),
            (width, height),
            "{}: size",
            case.name
        );
        let (fraction, diff) = compare(&got, &expected);
        println!(
            "{:<24} {:>8.4}% of pixels within distance 2",
            case.name,
            fraction * 100.0
        );
        if fraction < PASS_FRACTION {
            std::fs::create_dir_all(&out_dir).unwrap();
            let render_path = out_dir.join(format!("{}.png", case.name));
            let diff_path = out_dir.join(format!("{}-diff.png", case.name));
            got.write_png(&render_path).unwrap();
            diff.write_png(&diff_path).unwrap();
            failures.push(format!(
                "{}: {:.4}% similar (render {}, difference {})",
                case.name,
                fraction * 100.0,
                render_path.display(),
                diff_path.display()
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "failing cases:\n{}",
        failures.join("\n")
    );
}
