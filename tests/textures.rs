//! Texture maps in OBJ/MTL scenes: texture coordinates, filtering and addressing,
//! sRGB decoding, MTL map options, cutouts, missing files, and what the integrators
//! make of textured values. Each test writes its own tiny images and scene.

use crate::support;

use support::write_png;

use std::path::{Path, PathBuf};

use raytracer::material::Material;
use raytracer::math::{Float, Ray, Vec2, Vec3};
use raytracer::{BvhParams, Film, Mode, RenderOptions, Scene, formats, render};

/// A unit square at `z` from (-1, -1) to (1, 1), texture coordinates (0, 0) at the
/// bottom left to `(u_max, v_max)` at the top right, as OBJ text starting after
/// `vertices_before` vertices and texture coordinates.
fn square(z: Float, u_max: Float, v_max: Float, material: &str, before: usize) -> String {
    let b = before;
    format!(
        "v -1 -1 {z}\nv 1 -1 {z}\nv 1 1 {z}\nv -1 1 {z}\n\
         vt 0 0\nvt {u_max} 0\nvt {u_max} {v_max}\nvt 0 {v_max}\n\
         usemtl {material}\n\
         f {}/{} {}/{} {}/{} {}/{}\n",
        b + 1,
        b + 1,
        b + 2,
        b + 2,
        b + 3,
        b + 3,
        b + 4,
        b + 4
    )
}

/// Writes `scene.obj` (with `mtllib scene.mtl` first) and `scene.mtl` into `dir`.
fn write_scene(dir: &Path, obj: &str, mtl: &str) -> PathBuf {
    std::fs::write(dir.join("scene.mtl"), mtl).unwrap();
    let path = dir.join("scene.obj");
    std::fs::write(&path, format!("mtllib scene.mtl\n{obj}")).unwrap();
    path
}

fn build(path: &Path) -> Scene {
    Scene::build(formats::load_obj(path).unwrap(), &BvhParams::default())
}

/// A ray from (x, y, 1) straight down -z.
fn down(x: Float, y: Float) -> Ray {
    Ray::new(Vec3::new(x, y, 1.0), Vec3::NEG_Z)
}

/// The material of the closest hit of `ray` and the texture coordinates there.
fn material_at<'s>(scene: &'s Scene, ray: &Ray) -> (&'s Material, Vec2) {
    let hit = scene.intersect(ray).expect("the ray hits the square");
    (&scene.materials[hit.material.0 as usize], hit.uv)
}

fn close(a: Vec3, b: Vec3, tolerance: Float) -> bool {
    (a - b).abs().max_element() <= tolerance
}

/// Renders from (0, 0, 1) looking down -z at 90 degrees: at distance 1 the view
/// spans exactly the square at z = 0.
fn render_square(scene: &Scene, size: u32, mode: Mode, depth: u32, spp: u32) -> Film {
    let options = RenderOptions {
        width: size,
        height: size,
        fov_degrees: 90.0,
        look_from: Vec3::new(0.0, 0.0, 1.0),
        look_to: Vec3::ZERO,
        mode,
        depth,
        samples_per_pixel: spp,
        ..RenderOptions::default()
    };
    options.validate().unwrap();
    render(scene, &options)
}

#[test]
fn u_goes_right_v_goes_up_and_row_zero_is_the_top_of_the_image() {
    let dir = tempfile::tempdir().unwrap();
    // Top row red, green; bottom row blue, white.
    write_png(
        &dir.path().join("quadrants.png"),
        2,
        2,
        3,
        &[255, 0, 0, 0, 255, 0, 0, 0, 255, 255, 255, 255],
    );
    let path = write_scene(
        dir.path(),
        &square(0.0, 1.0, 1.0, "m", 0),
        "newmtl m\nKa 1 1 1\nKd 0 0 0\nmap_Ka quadrants.png\n",
    );
    let scene = build(&path);
    // Each pixel of a 2x2 image looks at one texel's centre: the image is the texture.
    let film = render_square(&scene, 2, Mode::Full, 1, 1);
    let expected = [Vec3::X, Vec3::Y, Vec3::Z, Vec3::ONE];
    for (i, (&got, want)) in film.pixels.iter().zip(expected).enumerate() {
        assert!(close(got, want, 1e-4), "pixel {i}: {got}, expected {want}");
    }
    // Texture coordinates are those of the corners, interpolated.
    let (_, uv) = material_at(&scene, &down(0.5, -0.5));
    assert!(
        (uv - Vec2::new(0.75, 0.25)).abs().max_element() < 1e-6,
        "{uv}"
    );
}

#[test]
fn colour_maps_are_decoded_from_srgb_before_bilinear_filtering() {
    let dir = tempfile::tempdir().unwrap();
    // Two texels side by side: black and sRGB 255 (linear 1), and a grey one whose
    // sRGB value 188 is linear 0.5029.
    write_png(&dir.path().join("ramp.png"), 2, 1, 1, &[0, 255]);
    write_png(&dir.path().join("grey.png"), 1, 1, 1, &[188]);
    let obj = format!(
        "{}{}",
        square(0.0, 1.0, 1.0, "ramp", 0),
        square(-1.0, 1.0, 1.0, "grey", 4)
    );
    let path = write_scene(
        dir.path(),
        &obj,
        "newmtl ramp\nKd 1 1 1\nmap_Kd -clamp on ramp.png\nnewmtl grey\nKd 0.5 1 1\nmap_Kd grey.png\n",
    );
    let scene = build(&path);
    // Texel centres at u = 1/4 and 3/4; half-way between them the mean of the
    // *linear* values (decoding after filtering would give 0.214), a quarter of the
    // way a quarter.
    for (x, expected) in [
        (-0.5, 0.0),
        (0.5, 1.0),
        (0.0, 0.5),
        (-0.25, 0.25),
        (-0.9, 0.0),
    ] {
        let (material, uv) = material_at(&scene, &down(x, 0.0));
        let kd = material.at(uv).diffuse;
        assert!(
            close(kd, Vec3::splat(expected), 1e-5),
            "x = {x}: {kd}, expected {expected}"
        );
    }
    // The map multiplies Kd, channel by channel.
    let grey = &scene.materials[1];
    let kd = grey.at(Vec2::new(0.5, 0.5)).diffuse;
    let linear = 0.502_886;
    assert!(
        close(kd, Vec3::new(0.5 * linear, linear, linear), 1e-5),
        "{kd}"
    );
}

#[test]
fn coordinates_outside_the_unit_square_repeat_unless_the_map_clamps() {
    let dir = tempfile::tempdir().unwrap();
    write_png(&dir.path().join("ramp.png"), 2, 1, 1, &[0, 255]);
    // u runs from 0 to 2 over the square.
    let obj = format!(
        "{}{}",
        square(0.0, 2.0, 1.0, "repeat", 0),
        square(-1.0, 2.0, 1.0, "clamp", 4)
    );
    let path = write_scene(
        dir.path(),
        &obj,
        "newmtl repeat\nKd 1 1 1\nmap_Kd ramp.png\nnewmtl clamp\nKd 1 1 1\nmap_Kd -clamp on ramp.png\n",
    );
    let scene = build(&path);
    let repeat = &scene.materials[0];
    let clamp = &scene.materials[1];
    // u = 1.25: repeat reads u = 0.25 (the black texel's centre); clamp reads past the
    // right edge (the white texel).
    let uv = Vec2::new(1.25, 0.5);
    assert_eq!(repeat.at(uv).diffuse, Vec3::ZERO);
    assert_eq!(clamp.at(uv).diffuse, Vec3::ONE);
    // u = 1.0 under repeat is half-way between the last texel and the first one
    // again; under clamp, the white texel.
    assert!(close(
        repeat.at(Vec2::new(1.0, 0.5)).diffuse,
        Vec3::splat(0.5),
        1e-6
    ));
    assert_eq!(clamp.at(Vec2::new(1.0, 0.5)).diffuse, Vec3::ONE);
    // And the same through the scene: the right half of the repeating square shows
    // the ramp a second time.
    let (material, uv) = material_at(&scene, &down(0.75, 0.0));
    assert!((uv.x - 1.75).abs() < 1e-5);
    assert_eq!(material.at(uv).diffuse, Vec3::ONE);
}

#[test]
fn map_options_are_parsed_and_file_names_keep_their_spaces() {
    let dir = tempfile::tempdir().unwrap();
    write_png(&dir.path().join("my texture file.png"), 2, 1, 1, &[0, 255]);
    let mtl = "newmtl m\nKd 1 1 1\n\
        map_Kd -s 2 1 1 -o 0.5 0 0 -clamp off -bm 1 -blendu on -blendv off -boost 1.5 \
        -texres 512 -mm 0 1 -t 0 0 0 -imfchan l -cc off -type sphere my texture file.png \n\
        map_d -imfchan r my texture file.png\n";
    let path = write_scene(dir.path(), &square(0.0, 1.0, 1.0, "m", 0), mtl);
    let description = formats::load_obj(&path).unwrap();
    assert!(
        description.warnings.is_empty(),
        "{:?}",
        description.warnings
    );
    let maps = description.materials[0].maps.as_ref().unwrap();
    let diffuse = maps.diffuse.as_ref().unwrap();
    assert!(diffuse.texture.path.ends_with("my texture file.png"));
    assert_eq!(diffuse.options.scale, Vec2::new(2.0, 1.0));
    assert_eq!(diffuse.options.offset, Vec2::new(0.5, 0.0));
    // One file named twice is read once.
    let cutout = maps.cutout.as_ref().unwrap().map.as_ref().unwrap();
    assert!(std::sync::Arc::ptr_eq(&diffuse.texture, &cutout.texture));
    // -s 2 then -o 0.5: u = 0 reads 0.5 (half-way, repeat), u = 0.125 reads 0.75.
    let material = &description.materials[0];
    assert!(close(
        material.at(Vec2::new(0.125, 0.5)).diffuse,
        Vec3::ONE,
        1e-6
    ));
    assert!(close(
        material.at(Vec2::new(0.0, 0.5)).diffuse,
        Vec3::splat(0.5),
        1e-6
    ));
}

#[test]
fn a_bad_map_option_is_an_error_naming_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_scene(
        dir.path(),
        &square(0.0, 1.0, 1.0, "m", 0),
        "newmtl m\nKd 1 1 1\nmap_Kd -clamp maybe t.png\n",
    );
    let error = formats::load_obj(&path).unwrap_err().to_string();
    assert!(
        error.ends_with("scene.mtl:3: '-clamp' takes on or off, found 'maybe'"),
        "{error}"
    );
    let path = write_scene(
        dir.path(),
        &square(0.0, 1.0, 1.0, "m", 0),
        "newmtl m\nmap_Kd -s\n",
    );
    let error = formats::load_obj(&path).unwrap_err().to_string();
    assert!(
        error.ends_with("scene.mtl:2: '-s' needs 1 value, found 0"),
        "{error}"
    );
}

#[test]
fn a_missing_texture_is_a_warning_naming_the_mtl_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("broken.png"), b"not a png at all").unwrap();
    let path = write_scene(
        dir.path(),
        &square(0.0, 1.0, 1.0, "m", 0),
        "newmtl m\nKa 0.25 0.5 1\n\nmap_Ka missing.png\nmap_Kd broken.png\n",
    );
    let description = formats::load_obj(&path).unwrap();
    let mtl = dir.path().join("scene.mtl");
    let warnings = &description.warnings;
    assert_eq!(warnings.len(), 2, "{warnings:?}");
    assert!(
        warnings[0].starts_with(&format!(
            "{}:4: cannot read texture 'missing.png': ",
            mtl.display()
        )) && warnings[0].ends_with("; the surface renders without it"),
        "{warnings:?}"
    );
    assert!(
        warnings[1].starts_with(&format!(
            "{}:5: cannot read texture 'broken.png': ",
            mtl.display()
        )),
        "{warnings:?}"
    );
    // The material renders with its constants alone.
    assert!(description.materials[0].maps.is_none());
    let scene = Scene::build(description, &BvhParams::default());
    let film = render_square(&scene, 2, Mode::Full, 1, 1);
    assert!(film.pixels.iter().all(|&p| p == Vec3::new(0.25, 0.5, 1.0)));
}

#[test]
fn windows_paths_find_the_texture_beside_the_mtl_file() {
    let dir = tempfile::tempdir().unwrap();
    write_png(&dir.path().join("wood.png"), 1, 1, 3, &[255, 0, 0]);
    let path = write_scene(
        dir.path(),
        &square(0.0, 1.0, 1.0, "m", 0),
        "newmtl m\nKd 1 1 1\nmap_Kd C:\\Users\\artist\\textures\\wood.png\n",
    );
    let description = formats::load_obj(&path).unwrap();
    assert!(
        description.warnings.is_empty(),
        "{:?}",
        description.warnings
    );
    let material = &description.materials[0];
    assert_eq!(material.at(Vec2::ZERO).diffuse, Vec3::X);
}

/// A square at z = 0 cut out on its left half (`map_d` from a texture whose left
/// texel has alpha 0), in front of an opaque square at z = -1; a light at `light`.
fn cutout_scene(dir: &Path, light: &str, imfchan: &str, texture: (u32, &[u8])) -> Scene {
    let (channels, texels) = texture;
    write_png(&dir.join("mask.png"), 2, 1, channels, texels);
    let obj = format!(
        "{}{}{light}",
        square(0.0, 1.0, 1.0, "leaf", 0),
        square(-1.0, 1.0, 1.0, "wall", 4)
    );
    let path = write_scene(
        dir,
        &obj,
        &format!(
            "newmtl leaf\nKa 1 0 0\nKd 0 0 0\nmap_d -clamp on {imfchan}mask.png\nnewmtl wall\nKa 0 0 0.1\nKd 0 1 0\n"
        ),
    );
    build(&path)
}

#[test]
fn map_d_cuts_the_surface_out_for_camera_and_shadow_rays() {
    let dir = tempfile::tempdir().unwrap();
    // Grey + alpha: the left texel transparent, the right one opaque.
    let scene = cutout_scene(dir.path(), "P 0 0 5 1 1 1\n", "", (2, &[255, 0, 255, 255]));
    // Camera rays: through the left half to the wall, stopped on the right half.
    assert_eq!(scene.intersect(&down(-0.5, 0.0)).unwrap().t, 2.0);
    assert_eq!(scene.intersect(&down(0.5, 0.0)).unwrap().t, 1.0);
    // Shadow rays from the wall up to the light: free on the left only.
    let up = |x| Ray::new(Vec3::new(x, 0.0, -1.0), Vec3::Z);
    assert!(!scene.occluded(&up(-0.5), 6.0));
    assert!(scene.occluded(&up(0.5), 6.0));
    // The linear scan agrees with the BVH.
    assert_eq!(scene.intersect_linear(&down(-0.5, 0.0)).unwrap().t, 2.0);

    // Rendered at 4x4: pixel (1, 1) looks through the leaf's left half at the lit
    // wall (Ka + Kd n.l, green), pixel (2, 1) at the leaf's right half (its Ka, red).
    let film = render_square(&scene, 4, Mode::Full, 1, 1);
    let wall = film.pixels[5];
    assert!(
        wall.x == 0.0 && wall.y > 0.9 && (wall.z - 0.1).abs() < 1e-6,
        "{wall}"
    );
    assert_eq!(film.pixels[6], Vec3::X);
    // Seen obliquely: a wall point behind the opaque half is in the leaf's shadow,
    // one behind the cut-out half is lit through it.
    let to_wall = |x: Float| {
        let target = Vec3::new(x, 0.0, -1.0);
        let from = Vec3::new(-0.9, 0.0, -0.5);
        Ray::new(from, (target - from).normalize())
    };
    let lit = scene.intersect(&to_wall(-0.5)).unwrap();
    let shadowed = scene.intersect(&to_wall(0.5)).unwrap();
    let light = Vec3::new(0.0, 0.0, 5.0);
    let (ray, distance) = lit.spawn_ray_to(light);
    assert!(!scene.occluded(&ray, distance));
    let (ray, distance) = shadowed.spawn_ray_to(light);
    assert!(scene.occluded(&ray, distance));
}

#[test]
fn map_d_reads_the_channel_imfchan_names() {
    let dir = tempfile::tempdir().unwrap();
    // RGB without alpha: red 0 on the left, 255 on the right; the other channels the
    // other way round. `-imfchan r` cuts out the left, luminance (the default for an
    // image without alpha) is the mean-ish of the channels: dark on the left too.
    let scene = cutout_scene(
        dir.path(),
        "",
        "-imfchan r ",
        (3, &[0, 255, 255, 255, 0, 0]),
    );
    assert_eq!(scene.intersect(&down(-0.5, 0.0)).unwrap().t, 2.0);
    assert_eq!(scene.intersect(&down(0.5, 0.0)).unwrap().t, 1.0);
    let scene = cutout_scene(
        dir.path(),
        "",
        "-imfchan g ",
        (3, &[0, 255, 255, 255, 0, 0]),
    );
    assert_eq!(scene.intersect(&down(-0.5, 0.0)).unwrap().t, 1.0);
    assert_eq!(scene.intersect(&down(0.5, 0.0)).unwrap().t, 2.0);
}

#[test]
fn path_mode_uses_textured_emission_and_diffuse_colour() {
    let dir = tempfile::tempdir().unwrap();
    write_png(
        &dir.path().join("quadrants.png"),
        2,
        2,
        3,
        &[255, 0, 0, 0, 255, 0, 0, 0, 255, 255, 255, 255],
    );
    let path = write_scene(
        dir.path(),
        &square(0.0, 1.0, 1.0, "m", 0),
        "newmtl m\nKe 2 2 2\nKd 0 0 0\nmap_Ke quadrants.png\n",
    );
    let scene = build(&path);
    // Depth 1: emitters seen directly, nothing else.
    let film = render_square(&scene, 2, Mode::Path, 1, 1);
    let expected = [Vec3::X, Vec3::Y, Vec3::Z, Vec3::ONE].map(|c| c * 2.0);
    for (i, (&got, want)) in film.pixels.iter().zip(expected).enumerate() {
        assert!(close(got, want, 1e-3), "pixel {i}: {got}, expected {want}");
    }

    // A diffuse square, black on its left and white on its right, lit by a point
    // light: the left pixels stay black in path mode as in full mode.
    write_png(&dir.path().join("halves.png"), 2, 1, 1, &[0, 255]);
    let path = write_scene(
        dir.path(),
        &format!("{}P 0 0 1 1 1 1\n", square(0.0, 1.0, 1.0, "m", 0)),
        "newmtl m\nKd 0.5 0.5 0.5\nmap_Kd -clamp on halves.png\n",
    );
    let scene = build(&path);
    for mode in [Mode::Path, Mode::Full] {
        let film = render_square(&scene, 2, mode, 2, 1);
        assert_eq!(film.pixels[0], Vec3::ZERO, "{mode:?}");
        assert_eq!(film.pixels[2], Vec3::ZERO, "{mode:?}");
        assert!(
            film.pixels[1].min_element() > 0.01,
            "{mode:?}: {}",
            film.pixels[1]
        );
    }
}

/// The shading normal at the centre of a square at z = 0 whose texture coordinates
/// run `u` along +x (or -x when `mirrored`), with `statement` (a bump or normal map
/// line) in its material, seen from +z.
fn shading_normal(dir: &Path, statement: &str, mirrored: bool) -> (Vec3, Vec<String>) {
    let u_max = if mirrored { -1.0 } else { 1.0 };
    let path = write_scene(
        dir,
        &square(0.0, u_max, 1.0, "m", 0),
        &format!("newmtl m\nKd 1 1 1\n{statement}\n"),
    );
    let description = formats::load_obj(&path).unwrap();
    let warnings = description.warnings.clone();
    let scene = Scene::build(description, &BvhParams::default());
    (scene.intersect(&down(0.1, 0.1)).unwrap().ns, warnings)
}

#[test]
fn normal_maps_tilt_the_shading_normal_in_the_frame_of_the_texture_coordinates() {
    let dir = tempfile::tempdir().unwrap();
    // One texel: tangent-space normal (0.6, 0, 0.8), red along u, blue out.
    write_png(&dir.path().join("normal.png"), 1, 1, 3, &[204, 128, 230]);
    let (ns, warnings) = shading_normal(dir.path(), "norm normal.png", false);
    assert!(warnings.is_empty(), "{warnings:?}");
    assert!(close(ns, Vec3::new(0.6, 0.0, 0.8), 0.01), "{ns}");
    // With u running the other way, the tangent is -x and so is the tilt.
    let (ns, _) = shading_normal(dir.path(), "norm normal.png", true);
    assert!(close(ns, Vec3::new(-0.6, 0.0, 0.8), 0.01), "{ns}");
    // A `bump` statement naming a normal map (pale blue, as exporters write them) is
    // a normal map: (0.28, 0, 0.96).
    write_png(&dir.path().join("pale.png"), 1, 1, 3, &[163, 128, 250]);
    let (ns, _) = shading_normal(dir.path(), "map_Bump pale.png", false);
    assert!(close(ns, Vec3::new(0.28, 0.0, 0.96), 0.01), "{ns}");
}

#[test]
fn bump_maps_tilt_the_normal_down_their_slope_scaled_by_bm() {
    let dir = tempfile::tempdir().unwrap();
    // Heights rising along u by 0.2 a texel (grey 0, 51, 102, ... wrapping around at
    // the far end, away from the point looked at), constant along v.
    let row: Vec<u8> = (0..8).map(|i| (i * 51 % 256) as u8).collect();
    let texels: Vec<u8> = row.iter().cycle().take(64).copied().collect();
    write_png(&dir.path().join("height.png"), 8, 8, 1, &texels);
    // Slope 0.2 per texel: the normal tilts towards -u, as (-0.2, 0, 1) normalized.
    let expected = Vec3::new(-0.2, 0.0, 1.0).normalize();
    let (ns, warnings) = shading_normal(dir.path(), "bump -clamp on height.png", false);
    assert!(warnings.is_empty(), "{warnings:?}");
    assert!(close(ns, expected, 0.01), "{ns}, expected {expected}");
    // `-bm 2` doubles the slope; a flat map leaves the normal alone.
    let (ns, _) = shading_normal(dir.path(), "bump -bm 2 -clamp on height.png", false);
    let expected = Vec3::new(-0.4, 0.0, 1.0).normalize();
    assert!(close(ns, expected, 0.01), "{ns}, expected {expected}");
    write_png(&dir.path().join("flat.png"), 2, 2, 1, &[90; 4]);
    let (ns, _) = shading_normal(dir.path(), "bump flat.png", false);
    assert_eq!(ns, Vec3::Z);
}

#[test]
fn texture_coordinates_are_kept_only_where_a_map_can_use_them() {
    let dir = tempfile::tempdir().unwrap();
    write_png(&dir.path().join("t.png"), 1, 1, 1, &[255]);
    let plain = write_scene(
        dir.path(),
        &square(0.0, 1.0, 1.0, "m", 0),
        "newmtl m\nKd 1 1 1\n",
    );
    let description = formats::load_obj(&plain).unwrap();
    assert_eq!(description.texcoords.len(), 4);
    assert!(description.triangle_texcoords.is_empty());
    let textured = write_scene(
        dir.path(),
        &square(0.0, 1.0, 1.0, "m", 0),
        "newmtl m\nKd 1 1 1\nmap_Kd t.png\n",
    );
    let description = formats::load_obj(&textured).unwrap();
    assert_eq!(
        description.triangle_texcoords,
        vec![Some([0, 1, 2]), Some([0, 2, 3])]
    );
}

#[test]
fn an_image_claiming_an_absurd_size_is_a_warning_not_a_crash() {
    let dir = tempfile::tempdir().unwrap();
    // A PNG header claiming 100000 x 100000 RGBA texels (40 GB), and no data.
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut header = b"IHDR".to_vec();
    header.extend_from_slice(&100_000u32.to_be_bytes());
    header.extend_from_slice(&100_000u32.to_be_bytes());
    header.extend_from_slice(&[8, 6, 0, 0, 0]);
    png.extend_from_slice(&13u32.to_be_bytes());
    png.extend_from_slice(&header);
    let crc = {
        // CRC-32 of the chunk type and data, as PNG wants it.
        let mut crc = 0xFFFF_FFFFu32;
        for &byte in &header {
            crc ^= u32::from(byte);
            for _ in 0..8 {
                crc = if crc & 1 != 0 {
                    (crc >> 1) ^ 0xEDB8_8320
                } else {
                    crc >> 1
                };
            }
        }
        !crc
    };
    png.extend_from_slice(&crc.to_be_bytes());
    std::fs::write(dir.path().join("huge.png"), &png).unwrap();
    let path = write_scene(
        dir.path(),
        &square(0.0, 1.0, 1.0, "m", 0),
        "newmtl m\nKd 1 1 1\nmap_Kd huge.png\n",
    );
    let description = formats::load_obj(&path).unwrap();
    assert_eq!(description.warnings.len(), 1, "{:?}", description.warnings);
    assert!(
        description.warnings[0].contains("scene.mtl:3: cannot read texture 'huge.png': "),
        "{:?}",
        description.warnings
    );
    assert!(description.materials[0].maps.is_none());
}

/// A diffuse floor (Kd 0.5) at z = 0 under a square emitter at z = 1 from (-1, -1) to
/// (1, 1) facing down, `Ke 4` times `map_Ke halves.png` (black on the left, white on
/// the right, clamped: u = (x + 1) / 2), seen by 16 x 16 pixels that all look, through
/// a field of view of a thousandth of a degree, at the floor point (0.25, 0, 0).
/// Returns the scene, the options and the radiance there by quadrature over the
/// emitter: Kd / pi times the integral of Le cos cos' / r^2 = Le / r^4.
fn textured_emitter_over_a_floor(dir: &Path) -> (Scene, RenderOptions, Float) {
    write_png(&dir.join("halves.png"), 2, 1, 1, &[0, 255]);
    let obj = "v -2 -2 0\nv 2 -2 0\nv 2 2 0\nv -2 2 0\nusemtl floor\nf 1 2 3 4\n\
               v -1 -1 1\nv -1 1 1\nv 1 1 1\nv 1 -1 1\n\
               vt 0 0\nvt 0 1\nvt 1 1\nvt 1 0\n\
               usemtl light\nf 5/1 6/2 7/3 8/4\n";
    let mtl = "newmtl floor\nKd 0.5 0.5 0.5\n\
               newmtl light\nKd 0 0 0\nKe 4 4 4\nmap_Ke -clamp on halves.png\n";
    let scene = build(&write_scene(dir, obj, mtl));
    let light = scene.materials.iter().find(|m| m.name == "light").unwrap();
    let x = Vec3::new(0.25, 0.0, 0.0);
    let n = 1000;
    let mut sum = 0.0f64;
    for i in 0..n {
        for j in 0..n {
            let (u, v) = (
                (i as Float + 0.5) / n as Float,
                (j as Float + 0.5) / n as Float,
            );
            let y = Vec3::new(2.0 * u - 1.0, 2.0 * v - 1.0, 1.0);
            let r2 = (y - x).length_squared();
            let le = light.at(Vec2::new(u, v)).emission.x;
            sum += f64::from(le / (r2 * r2)) * 4.0 / (n * n) as f64;
        }
    }
    let expected = (0.5 / std::f64::consts::PI * sum) as Float;
    let options = RenderOptions {
        width: 16,
        height: 16,
        fov_degrees: 0.001,
        look_from: Vec3::new(0.25, -3.0, 0.5),
        look_to: x,
        mode: Mode::Path,
        // Direct light only: the floor's light sample and the ray it scatters.
        depth: 2,
        samples_per_pixel: 64,
        default_light: false,
        ..RenderOptions::default()
    };
    options.validate().unwrap();
    (scene, options, expected)
}

/// The mean of the pixels' red values and its standard error (the pixels are
/// independent estimates of the same radiance).
fn mean_and_error(film: &Film) -> (Float, Float) {
    let values: Vec<f64> = film.pixels.iter().map(|p| f64::from(p.x)).collect();
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let variance = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean as Float, (variance / n).sqrt() as Float)
}

#[test]
fn light_sampling_sees_textured_emission_as_scattered_rays_do() {
    // Light sampling with multiple importance sampling, and scattered rays alone (the
    // area lights emptied), both estimate the quadrature's value: a light sample that
    // took `Ke` for the emitter's radiance, ignoring its map, would count the black
    // half as lit. Fixed seed: the figures are the same on every run.
    let dir = tempfile::tempdir().unwrap();
    let (scene, options, expected) = textured_emitter_over_a_floor(dir.path());
    let mut scattered_only = scene.clone();
    scattered_only.area_lights = Default::default();
    for (what, scene) in [("light sampling", &scene), ("scattering", &scattered_only)] {
        let (mean, error) = mean_and_error(&render(scene, &options));
        eprintln!("{what}: {mean} +- {error}, expected {expected}");
        assert!(
            (mean - expected).abs() < 4.0 * error,
            "{what}: {mean} +- {error}, expected {expected}"
        );
        assert!(
            error < 0.02 * expected,
            "{what}: too noisy to tell: {error}"
        );
    }
}

#[test]
fn hits_interpolate_texture_coordinates_only_on_materials_with_maps() {
    // Two squares with the same texture coordinates, one above the other: the top
    // one's material has no map, so its hits skip the interpolation (uv stays zero);
    // the bottom one's have theirs.
    let dir = tempfile::tempdir().unwrap();
    write_png(&dir.path().join("t.png"), 1, 1, 1, &[255]);
    let obj = format!(
        "{}{}",
        square(0.5, 1.0, 1.0, "plain", 0),
        square(0.0, 1.0, 1.0, "mapped", 4)
    );
    let path = write_scene(
        dir.path(),
        &obj,
        "newmtl plain\nKd 1 1 1\nnewmtl mapped\nKd 1 1 1\nmap_Kd t.png\n",
    );
    let scene = build(&path);
    let (material, uv) = material_at(&scene, &down(0.5, 0.5));
    assert_eq!((material.name.as_str(), uv), ("plain", Vec2::ZERO));
    let below = Ray::new(Vec3::new(0.5, 0.5, 0.25), Vec3::NEG_Z);
    let (material, uv) = material_at(&scene, &below);
    assert_eq!(material.name, "mapped");
    assert!(
        (uv - Vec2::new(0.75, 0.75)).abs().max_element() < 1e-6,
        "{uv}"
    );
}

/// Two squares in `dir`, one mapping its `tex.png`, the other its `tex.EXT`: their
/// materials as read, with no warning.
fn beside_png(dir: &Path, ext: &str) -> [Material; 2] {
    let obj = format!(
        "{}{}",
        square(0.0, 1.0, 1.0, "png", 0),
        square(-1.0, 1.0, 1.0, ext, 4)
    );
    let mtl =
        format!("newmtl png\nKd 1 1 1\nmap_Kd tex.png\nnewmtl {ext}\nKd 1 1 1\nmap_Kd tex.{ext}\n");
    let description = formats::load_obj(&write_scene(dir, &obj, &mtl)).unwrap();
    assert!(
        description.warnings.is_empty(),
        "{:?}",
        description.warnings
    );
    [0, 1].map(|m| description.materials[m].clone())
}

#[test]
fn gif_textures_read_as_the_same_texels_in_png() {
    // pybullet_data's textured_sphere_smooth.mtl maps `checker_huge.gif`: GIF, which
    // stb_image (pybullet, Assimp) reads, is read here too, as its first frame.
    let dir = tempfile::tempdir().unwrap();
    let rgb: Vec<u8> = (0..4 * 2 * 3).map(|i| (i * 29 % 251) as u8).collect();
    write_png(&dir.path().join("tex.png"), 4, 2, 3, &rgb);
    let rgba: Vec<u8> = rgb
        .chunks(3)
        .flat_map(|p| [p[0], p[1], p[2], 255])
        .collect();
    let file = std::fs::File::create(dir.path().join("tex.gif")).unwrap();
    image::codecs::gif::GifEncoder::new(file)
        .encode(&rgba, 4, 2, image::ExtendedColorType::Rgba8)
        .unwrap();
    let [png, gif] = beside_png(dir.path(), "gif");
    let mut colours = Vec::new();
    for k in 0..8 {
        let uv = Vec2::new(
            (k % 4) as Float / 4.0 + 0.125,
            (k / 4) as Float / 2.0 + 0.25,
        );
        let colour = png.at(uv).diffuse;
        assert_eq!(gif.at(uv).diffuse, colour, "{uv}");
        colours.push(colour);
    }
    colours.dedup();
    assert_eq!(colours.len(), 8, "every texel its own colour: {colours:?}");
}

/// A DDS file of DXT1 blocks, each `[colour0, colour1, indices]`, `width` x
/// `height` texels (multiples of 4), no mipmaps; the header as Microsoft's DDS
/// reference describes it.
fn dxt1_dds(width: u32, height: u32, blocks: &[(u16, u16, u32)]) -> Vec<u8> {
    let mut header = [0u32; 31];
    header[0] = 124; // dwSize
    header[1] = 0x1 | 0x2 | 0x4 | 0x1000 | 0x80000; // CAPS HEIGHT WIDTH PIXELFORMAT LINEARSIZE
    header[2] = height;
    header[3] = width;
    header[4] = width.div_ceil(4) * height.div_ceil(4) * 8; // the top level's bytes
    header[18] = 32; // DDS_PIXELFORMAT: dwSize
    header[19] = 0x4; // DDPF_FOURCC
    header[20] = u32::from_le_bytes(*b"DXT1");
    header[26] = 0x1000; // DDSCAPS_TEXTURE
    let mut bytes = b"DDS ".to_vec();
    bytes.extend(header.iter().flat_map(|w| w.to_le_bytes()));
    for &(c0, c1, indices) in blocks {
        bytes.extend(c0.to_le_bytes());
        bytes.extend(c1.to_le_bytes());
        bytes.extend(indices.to_le_bytes());
    }
    bytes
}

#[test]
fn dds_textures_read_as_the_same_texels_in_png() {
    // Genesis's Airplane/airplane.mtl maps `textures/diffuse.dds` (DXT5), as 3ds Max
    // exports write: Blender and PIL (trimesh, Genesis) read DDS, so it is read here
    // too. Two 4x4 DXT1 blocks, one above the other: red over blue (RGB565 0xF800 and
    // 0x001F, every index 0: colour0), the same texels as the PNG beside it.
    let dir = tempfile::tempdir().unwrap();
    let dds = dxt1_dds(4, 8, &[(0xF800, 0, 0), (0x001F, 0, 0)]);
    std::fs::write(dir.path().join("tex.dds"), dds).unwrap();
    let rgb: Vec<u8> = (0..32)
        .flat_map(|i| if i < 16 { [255, 0, 0] } else { [0, 0, 255] })
        .collect();
    write_png(&dir.path().join("tex.png"), 4, 8, 3, &rgb);
    let [png, dds] = beside_png(dir.path(), "dds");
    for (v, colour) in [(0.75, Vec3::X), (0.25, Vec3::Z)] {
        let uv = Vec2::new(0.5, v);
        assert_eq!(png.at(uv).diffuse, colour, "{uv}");
        assert_eq!(dds.at(uv).diffuse, colour, "{uv}");
    }
}
