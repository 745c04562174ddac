//! The properties the fuzz targets check, shared with `tests/fuzz_regressions.rs`,
//! which replays every input a fuzzer ever failed on (the fuzz targets include this
//! file by path). A check panics when a property breaks; malformed input refused with
//! an error that names its file (and line) is a pass.
#![allow(dead_code)]

use std::path::Path;

use raytracer::math::{Float, Vec3};
use raytracer::{BvhParams, Film, Mode, RenderOptions, Scene, SceneDescription, SceneError};
use raytracer::{Material, formats, render};

/// The MTL file that the `obj` and `pipeline` checks place beside the OBJ.
pub const MTL_NAME: &str = "m.mtl";

/// What `m.mtl` holds for the `obj` check: one material of each kind.
pub const FIXED_MTL: &str = "newmtl matte\nKd 0.8 0.2 0.2\nnewmtl mirror\nKs 1 1 1\nNs 50\nal 0.2 0.8 0\nnewmtl glass\nNi 1.5\nal 0 0.1 0.9\nnewmtl glow\nKe 2 2 2\n";

/// In a `pipeline` input, the OBJ text comes before the first byte of this value and
/// the MTL text (written to `m.mtl`) after it.
pub const MTL_SEPARATOR: u8 = 0;

/// Image size of the pipeline renders: tiny, so that a run covers many scenes.
const WIDTH: u32 = 8;
const HEIGHT: u32 = 6;
/// Recursion depth of the pipeline's full-mode renders.
const DEPTH: u32 = 3;

/// Parses `data` as `dir/scene.obj` (with `dir/m.mtl` holding [`FIXED_MTL`], written
/// by the caller) and checks the result.
pub fn check_obj(data: &[u8], dir: &Path) {
    let path = dir.join("scene.obj");
    match formats::parse_obj(data, &path) {
        Ok(description) => check_description(&description),
        Err(err) => check_error(&err, data, &path),
    }
}

/// Parses `data` as an MTL file and checks the result.
pub fn check_mtl(data: &[u8]) {
    let path = Path::new("fuzz.mtl");
    match formats::parse_mtl(data, path) {
        Ok(library) => library.materials.iter().for_each(check_material),
        Err(err) => check_error(&err, data, path),
    }
}

/// Parses the OBJ part of `data` (with its MTL part as `dir/m.mtl`), builds the
/// scene and renders it in every mode from two cameras, checking the BVH, the film
/// and the 8-bit values.
pub fn check_pipeline(data: &[u8], dir: &Path) {
    let (obj, mtl) = match data.iter().position(|&b| b == MTL_SEPARATOR) {
        Some(i) => (&data[..i], &data[i + 1..]),
        None => (data, &[][..]),
    };
    std::fs::write(dir.join(MTL_NAME), mtl).expect("cannot write the fuzz MTL file");
    let path = dir.join("scene.obj");
    let description = match formats::parse_obj(obj, &path) {
        Ok(d) => d,
        Err(err) => return check_error(&err, obj, &path),
    };
    check_description(&description);
    let scene = Scene::build(description, &BvhParams::default());
    if let Err(err) = scene.validate() {
        panic!("{err}");
    }
    for (look_from, look_to) in cameras(&scene) {
        for mode in [Mode::Depth, Mode::Normal, Mode::Full] {
            let options = RenderOptions {
                width: WIDTH,
                height: HEIGHT,
                look_from,
                look_to,
                depth: DEPTH,
                mode,
                ..RenderOptions::default()
            };
            if options.validate().is_err() {
                continue;
            }
            check_film(&render(&scene, &options), mode);
        }
    }
}

/// The default camera, and one looking at the middle of the scene from outside it.
fn cameras(scene: &Scene) -> Vec<(Vec3, Vec3)> {
    let mut cameras = vec![(Vec3::ZERO, Vec3::NEG_Z)];
    let bounds = scene.bvh_summary().bounds;
    if !bounds.is_empty() {
        let centre = bounds.center();
        let reach = (bounds.max - bounds.min).length();
        let look_from = centre + Vec3::new(0.3, 0.4, 1.0).normalize() * reach;
        if centre.is_finite() && look_from.is_finite() {
            cameras.push((look_from, centre));
        }
    }
    cameras
}

/// Every film value finite (depth misses excepted), and every post-processed value
/// finite and in 0..=1.
pub fn check_film(film: &Film, mode: Mode) {
    for (i, v) in film.pixels.iter().enumerate() {
        let ok = match mode {
            Mode::Depth => v.x == v.y && v.y == v.z && v.x >= 0.0 && !v.x.is_nan(),
            _ => v.is_finite(),
        };
        assert!(ok, "{mode:?} film pixel {i} is {v}");
    }
    for (i, v) in film.display_values(mode).enumerate() {
        assert!(
            v.is_finite() && v.cmpge(Vec3::ZERO).all() && v.cmple(Vec3::ONE).all(),
            "{mode:?} display value of pixel {i} is {v}"
        );
    }
}

/// What the readers guarantee to the builder: finite numbers, indices in range.
pub fn check_description(d: &SceneDescription) {
    let finite = |v: &Vec3| v.is_finite();
    assert!(d.positions.iter().all(finite), "non-finite position");
    assert!(d.normals.iter().all(finite), "non-finite normal");
    assert!(d.texcoords.iter().all(|t| t.is_finite()));
    for t in &d.triangles {
        assert!(
            t.positions
                .iter()
                .all(|&i| (i as usize) < d.positions.len())
        );
        if let Some(ns) = t.normals {
            assert!(ns.iter().all(|&i| (i as usize) < d.normals.len()));
        }
        assert!((t.material.0 as usize) < d.materials.len());
    }
    for s in &d.spheres {
        assert!(s.center.is_finite() && s.radius.is_finite() && s.radius >= 0.0);
        assert!((s.material.0 as usize) < d.materials.len());
    }
    for light in &d.lights {
        assert!(light.position.is_finite() && light.intensity.is_finite());
    }
    d.materials.iter().for_each(check_material);
}

fn check_material(m: &Material) {
    let colours = [m.ambient, m.diffuse, m.specular, m.emission];
    assert!(colours.iter().all(|c| c.is_finite()), "{m:?}");
    let scalars: [Float; 3] = [m.shininess, m.ior, m.opacity];
    assert!(
        scalars.iter().chain(&m.albedo).all(|x| x.is_finite()),
        "{m:?}"
    );
}

/// An error must name a file; a parse error must also name a line of that file.
/// Messages stay short: tokens are quoted cut, so only the file name can be long.
fn check_error(err: &SceneError, data: &[u8], path: &Path) {
    let message = err.to_string();
    let at = match err {
        SceneError::Parse { path: at, line, .. } => {
            assert!(*line >= 1, "line 0 in '{message}'");
            if at == path {
                let lines = data.split(|&b| b == b'\n').count();
                assert!(*line <= lines, "line {line} of {lines} in '{message}'");
            }
            let prefix = format!("{}:{line}: ", at.display());
            assert!(message.starts_with(&prefix), "'{message}' lacks '{prefix}'");
            at
        }
        SceneError::Io { path: at, .. } => {
            let prefix = format!("{}: ", at.display());
            assert!(message.starts_with(&prefix), "'{message}' lacks '{prefix}'");
            at
        }
        _ => panic!("unexpected error kind: {message}"),
    };
    let limit = 1000 + at.as_os_str().len();
    assert!(message.len() < limit, "message of {} bytes", message.len());
}
