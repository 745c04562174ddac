//! The properties the fuzz targets check, shared with `tests/fuzz_regressions.rs`,
//! which replays every input a fuzzer ever failed on (the fuzz targets include this
//! file by path). A check panics when a property breaks; malformed input refused with
//! an error that names its file (and line) is a pass.
#![allow(dead_code)]

use std::path::Path;

use raytracer::material::BlendRule;
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

/// Parses `data` as a PLY file and checks the result.
pub fn check_ply(data: &[u8]) {
    let path = Path::new("fuzz.ply");
    match formats::parse_ply(data, path) {
        Ok(description) => check_description(&description),
        Err(err) => check_error(&err, data, path),
    }
}

/// The mesh files that the `toml` check places beside the scene file, for its
/// `[[mesh]]` tables to name: [`MTL_NAME`] (holding [`FIXED_MTL`]) and these.
pub const TOML_MESHES: [(&str, &str); 2] = [
    (
        "a.obj",
        "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl matte\nf 1 2 3\nusemtl glow\nsphere 0 0 -2 0.5\n",
    ),
    (
        "b.ply",
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
    ),
];

/// Writes [`TOML_MESHES`] and `m.mtl` into `dir`.
pub fn write_toml_meshes(dir: &Path) {
    std::fs::write(dir.join(MTL_NAME), FIXED_MTL).expect("cannot write the fuzz MTL file");
    for (name, text) in TOML_MESHES {
        std::fs::write(dir.join(name), text).expect("cannot write a fuzz mesh");
    }
}

/// Parses `data` as the scene file `dir/scene.toml` (with the files of
/// [`write_toml_meshes`] beside it), checks the description, and resolves the
/// options as the command line does: either is an error naming a file, or a
/// description the builder can take and options in range.
pub fn check_toml(data: &[u8], dir: &Path) {
    let path = dir.join("scene.toml");
    let loaded = match formats::parse_toml(data, &path) {
        Ok(loaded) => loaded,
        Err(err) => return check_error(&err, data, &path),
    };
    check_description(&loaded.description);
    if let Ok((description, options)) = loaded.resolve(Default::default()) {
        check_description(&description);
        assert!(
            options.validate().is_ok(),
            "resolved options fail validation"
        );
    }
}

/// In a `gltf` input, the glTF (JSON or GLB) comes first; after the first byte of
/// this value, if any, come the bytes of `b.bin` and after the next one those of
/// `t.png`, the files its buffers and images may name.
pub const GLTF_SEPARATOR: &[u8] = b"\n#FILE#\n";

/// Parses the glTF part of `data` as `dir/scene.gltf`, with its other parts as
/// `dir/b.bin` and `dir/t.png`, and checks the description and its textures.
pub fn check_gltf(data: &[u8], dir: &Path) {
    let mut parts = split_on(data, GLTF_SEPARATOR);
    let gltf = parts.next().unwrap_or_default();
    for name in ["b.bin", "t.png"] {
        let bytes = parts.next().unwrap_or_default();
        std::fs::write(dir.join(name), bytes).expect("cannot write a fuzz file");
    }
    let path = dir.join("scene.gltf");
    match formats::parse_gltf(gltf, &path) {
        Ok(loaded) => {
            check_description(&loaded.description);
            loaded.description.materials.iter().for_each(check_maps);
        }
        Err(err) => check_error(&err, gltf, &path),
    }
}

/// The pieces of `data` between occurrences of `separator`.
fn split_on<'a>(data: &'a [u8], separator: &'a [u8]) -> impl Iterator<Item = &'a [u8]> {
    let mut rest = Some(data);
    std::iter::from_fn(move || {
        let text = rest?;
        match text.windows(separator.len()).position(|w| w == separator) {
            Some(i) => {
                rest = Some(&text[i + separator.len()..]);
                Some(&text[..i])
            }
            None => {
                rest = None;
                Some(text)
            }
        }
    })
}

/// The image file that a `textures` input's MTL part may name.
pub const TEXTURE_NAME: &str = "t.png";

/// MTL text, then a NUL byte, then the bytes of `t.png`: parses the MTL as
/// `dir/m.mtl`, decoding the image for every map that names it, and samples every
/// material's maps.
pub fn check_textures(data: &[u8], dir: &Path) {
    let (mtl, image) = match data.iter().position(|&b| b == MTL_SEPARATOR) {
        Some(i) => (&data[..i], &data[i + 1..]),
        None => (data, &[][..]),
    };
    std::fs::write(dir.join(TEXTURE_NAME), image).expect("cannot write the fuzz image");
    let path = dir.join(MTL_NAME);
    match formats::parse_mtl(mtl, &path) {
        Ok(library) => {
            for material in &library.materials {
                check_material(material);
                check_maps(material);
            }
            for warning in &library.warnings {
                assert!(
                    warning.starts_with(&path.display().to_string()),
                    "{warning}"
                );
            }
        }
        Err(err) => check_error(&err, mtl, &path),
    }
}

/// Samples a material's maps at a few points, inside and outside `[0, 1]`: values
/// are never NaN, shading normals are unit vectors.
fn check_maps(m: &Material) {
    if m.maps.is_none() {
        return;
    }
    let points = [
        (0.0, 0.0),
        (0.5, 0.5),
        (0.999, 0.001),
        (1.0, 1.0),
        (-3.25, 7.5),
        (1e30, -1e30),
    ];
    for (u, v) in points {
        let uv = raytracer::math::Vec2::new(u, v);
        let values = m.at(uv);
        let colours = [
            values.ambient,
            values.diffuse,
            values.specular,
            values.emission,
        ];
        assert!(
            colours.iter().all(|c| !c.is_nan()),
            "{m:?} at {uv}: {values:?}"
        );
        assert!(!values.shininess.is_nan(), "{m:?} at {uv}: {values:?}");
        if let Some(maps) = &m.maps
            && let Some(n) = maps.tangent_normal(uv)
        {
            assert!((n.length() - 1.0).abs() < 1e-3, "{m:?} at {uv}: normal {n}");
        }
        if let Some(cutout) = m.cutout() {
            for rule in [
                BlendRule::Stochastic(0),
                BlendRule::Layer,
                BlendRule::Shadow,
            ] {
                cutout.keeps(uv, rule, 0);
            }
            assert!((0.0..=1.0).contains(&cutout.coverage(uv)), "{m:?} at {uv}");
        }
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
    // A vertex at a non-finite position may stay (a warning), but no triangle
    // uses it: nothing non-finite reaches the BVH.
    let used_finite = |t: &raytracer::description::TriangleDesc| {
        (t.positions.iter()).all(|&i| d.positions.get(i as usize).is_none_or(finite))
    };
    assert!(d.triangles.iter().all(used_finite), "non-finite position");
    // Likewise a non-finite normal or texture coordinate: no triangle uses it, so
    // nothing non-finite reaches shading.
    let all_finite = |corners: &Option<[u32; 3]>, finite: &dyn Fn(usize) -> bool| {
        corners.is_none_or(|c| c.iter().all(|&i| finite(i as usize)))
    };
    let normal = |i: usize| d.normals.get(i).is_none_or(finite);
    let texcoord = |i: usize| d.texcoords.get(i).is_none_or(|t| t.is_finite());
    assert!(
        d.triangle_normals.iter().all(|c| all_finite(c, &normal)),
        "non-finite normal"
    );
    assert!(
        d.triangle_texcoords
            .iter()
            .all(|c| all_finite(c, &texcoord)),
        "non-finite texture coordinate"
    );
    assert!(d.triangle_normals.is_empty() || d.triangle_normals.len() == d.triangles.len());
    for (i, t) in d.triangles.iter().enumerate() {
        assert!(
            t.positions
                .iter()
                .all(|&i| (i as usize) < d.positions.len())
        );
        if let Some(ns) = d.normals_of(i) {
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
        SceneError::Io { path: at, .. } | SceneError::Gltf { path: at, .. } => {
            let prefix = format!("{}: ", at.display());
            assert!(message.starts_with(&prefix), "'{message}' lacks '{prefix}'");
            at
        }
        SceneError::Element { path: at, .. } | SceneError::Included { path: at, .. } => {
            let prefix = format!("{}:", at.display());
            assert!(message.starts_with(&prefix), "'{message}' lacks '{prefix}'");
            at
        }
        _ => panic!("unexpected error kind: {message}"),
    };
    let limit = 1000 + at.as_os_str().len();
    assert!(message.len() < limit, "message of {} bytes", message.len());
}
