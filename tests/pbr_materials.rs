//! Physically based materials as the readers make them: glTF's core
//! metallic-roughness model and its extensions, Blender's MTL PBR statements, TOML's
//! physically based keys, and the warnings and errors about bad values. Every glTF
//! fixture is written here: one triangle per material, from a `.bin` beside it.

use crate::support;

use support::{render, write_png};

use std::path::{Path, PathBuf};
use std::process::Command;

use raytracer::formats::{self, LoadedScene};
use raytracer::material::Material;
use raytracer::math::{Float, Vec2, Vec3};
use raytracer::textures::{Channel, srgb_to_linear};

/// A 2 x 2 RGBA texture, texels top left, top right, bottom left, bottom right.
const TEXELS: [[u8; 4]; 4] = [
    [10, 64, 255, 200],
    [20, 255, 0, 100],
    [30, 128, 51, 0],
    [40, 0, 204, 255],
];

/// Where each texel's centre is in this renderer's texture coordinates (v up).
const TOP_LEFT: Vec2 = Vec2::new(0.25, 0.75);
const TOP_RIGHT: Vec2 = Vec2::new(0.75, 0.75);
const BOTTOM_RIGHT: Vec2 = Vec2::new(0.75, 0.25);

fn unit(byte: u8) -> Float {
    Float::from(byte) / 255.0
}

fn close(a: Float, b: Float) -> bool {
    (a - b).abs() < 1e-4
}

fn close3(a: Vec3, b: Vec3) -> bool {
    (a - b).abs().max_element() < 1e-4
}

/// A folder holding `tri.bin` (one triangle facing +z, with texture coordinates),
/// `rgba.png` (`TEXELS`), `grey.png` (2 x 2, one channel) and the glTF file written
/// by [`Fixture::gltf`].
struct Fixture(tempfile::TempDir);

impl Fixture {
    fn new() -> Fixture {
        let dir = tempfile::tempdir().unwrap();
        let mut bin = Vec::new();
        for v in [[-1.0f32, -1.0, 0.0], [1.0, -1.0, 0.0], [0.0, 1.0, 0.0]] {
            bin.extend(v.iter().flat_map(|x| x.to_le_bytes()));
        }
        for t in [[0.0f32, 1.0], [1.0, 1.0], [0.5, 0.0]] {
            bin.extend(t.iter().flat_map(|x| x.to_le_bytes()));
        }
        std::fs::write(dir.path().join("tri.bin"), bin).unwrap();
        write_png(&dir.path().join("rgba.png"), 2, 2, 4, &TEXELS.concat());
        write_png(&dir.path().join("grey.png"), 2, 2, 1, &[0, 85, 170, 255]);
        Fixture(dir)
    }

    /// Writes `name.gltf` with `materials` (a JSON array's items), one triangle
    /// per material, texture 0 = `rgba.png`, texture 1 = `grey.png`, and `extra`
    /// (more top-level members, each followed by a comma); returns its path.
    fn gltf(&self, name: &str, materials: &[&str], extra: &str) -> PathBuf {
        let meshes: Vec<String> = (0..materials.len())
            .map(|i| {
                format!(
                    r#"{{"primitives": [{{"attributes": {{"POSITION": 0, "TEXCOORD_0": 1}}, "material": {i}}}]}}"#
                )
            })
            .collect();
        let nodes: Vec<String> = (0..materials.len())
            .map(|i| format!(r#"{{"mesh": {i}}}"#))
            .collect();
        let roots: Vec<String> = (0..materials.len()).map(|i| i.to_string()).collect();
        let json = format!(
            r#"{{
  "asset": {{"version": "2.0"}},
  {extra}
  "buffers": [{{"uri": "tri.bin", "byteLength": 60}}],
  "bufferViews": [
    {{"buffer": 0, "byteOffset": 0, "byteLength": 36}},
    {{"buffer": 0, "byteOffset": 36, "byteLength": 24}}
  ],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [-1, -1, 0], "max": [1, 1, 0]}},
    {{"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"}}
  ],
  "images": [{{"uri": "rgba.png"}}, {{"uri": "grey.png"}}],
  "textures": [{{"source": 0}}, {{"source": 1}}],
  "materials": [{materials}],
  "meshes": [{meshes}],
  "nodes": [{nodes}],
  "scenes": [{{"nodes": [{roots}]}}],
  "scene": 0
}}"#,
            materials = materials.join(",\n"),
            meshes = meshes.join(", "),
            nodes = nodes.join(", "),
            roots = roots.join(", "),
        );
        let path = self.0.path().join(format!("{name}.gltf"));
        std::fs::write(&path, json).unwrap();
        path
    }

    fn load(&self, materials: &[&str], extra: &str) -> LoadedScene {
        let path = self.gltf("scene", materials, extra);
        formats::load(&path).unwrap_or_else(|e| panic!("{e}"))
    }

    /// The warnings, without the file name.
    fn warnings(&self, loaded: &LoadedScene) -> Vec<String> {
        let prefix = format!("{}: ", self.0.path().join("scene.gltf").display());
        loaded
            .description
            .warnings
            .iter()
            .map(|w| w.strip_prefix(&prefix).unwrap_or(w).to_owned())
            .collect()
    }
}

fn pbr(material: &Material) -> &raytracer::material::pbr::PbrMaterial {
    material
        .pbr
        .as_deref()
        .expect("a physically based material")
}

#[test]
fn gltf_core_factors_and_the_metallic_roughness_texture_channels() {
    let fixture = Fixture::new();
    let loaded = fixture.load(
        &[
            r#"{"name": "plain", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.25, 1, 1], "metallicFactor": 0.5, "roughnessFactor": 0.8}}"#,
            r#"{"name": "textured", "pbrMetallicRoughness": {"metallicFactor": 0.5, "roughnessFactor": 0.8,
                "metallicRoughnessTexture": {"index": 0}, "baseColorTexture": {"index": 0}},
                "emissiveFactor": [1, 0.5, 0], "emissiveTexture": {"index": 0},
                "normalTexture": {"index": 0, "scale": 0.5}, "occlusionTexture": {"index": 0}}"#,
            r#"{"name": "defaults"}"#,
        ],
        "",
    );
    assert!(
        fixture.warnings(&loaded).is_empty(),
        "{:?}",
        loaded.description.warnings
    );
    let m = &loaded.description.materials;
    let plain = pbr(&m[0]);
    assert_eq!(plain.base_color, Vec3::new(0.5, 0.25, 1.0));
    assert_eq!((plain.metallic, plain.roughness), (0.5, 0.8));
    assert!(m[0].maps.is_none());
    // glTF's defaults: white metal, fully rough.
    assert_eq!(
        *pbr(&m[2]),
        raytracer::material::pbr::PbrMaterial::default()
    );

    let textured = &m[1];
    let maps = textured.maps.as_deref().unwrap();
    // The base colour map is the physically based one, not Kd's.
    assert!(maps.diffuse.is_none() && maps.specular.is_none());
    assert!(maps.pbr.base_color.is_some());
    let roughness = maps.pbr.roughness.as_ref().unwrap();
    let metallic = maps.pbr.metallic.as_ref().unwrap();
    assert_eq!(roughness.options.channel, Channel::Green);
    assert_eq!(metallic.options.channel, Channel::Blue);
    assert!(std::sync::Arc::ptr_eq(
        &roughness.texture,
        &metallic.texture
    ));
    for (uv, texel) in [(TOP_LEFT, 0), (TOP_RIGHT, 1), (BOTTOM_RIGHT, 3)] {
        let values = textured.pbr_at(uv).unwrap();
        let [r, g, b, _] = TEXELS[texel];
        assert!(close(values.roughness, 0.8 * unit(g)), "{uv}: {values:?}");
        assert!(close(values.metallic, 0.5 * unit(b)), "{uv}: {values:?}");
        let base = Vec3::new(
            srgb_to_linear(unit(r)),
            srgb_to_linear(unit(g)),
            srgb_to_linear(unit(b)),
        );
        assert!(close3(values.base_color, base), "{uv}: {values:?}");
    }
    // Emission: the factor, times its texture.
    assert_eq!(textured.emission, Vec3::new(1.0, 0.5, 0.0));
    assert!(maps.emission.is_some());
    // The normal texture with its scale, which scales the tangent normal's x and y.
    let normal = maps.normal.as_ref().unwrap();
    assert_eq!(normal.options.bump_multiplier, 0.5);
    let n = maps.tangent_normal(TOP_LEFT).unwrap();
    let raw = Vec3::new(unit(10), unit(64), unit(255)) * 2.0 - Vec3::ONE;
    let want = Vec3::new(raw.x * 0.5, raw.y * 0.5, raw.z).normalize();
    assert!(close3(n, want), "{n} vs {want}");
}

/// `alphaMode: BLEND` is stochastic transparency (`Cutout::blend`) with the base
/// colour's alpha, without a warning; `MASK` stays a cutout at `alphaCutoff`.
#[test]
fn blend_is_stochastic_transparency_and_mask_a_cutout() {
    let fixture = Fixture::new();
    let loaded = fixture.load(
        &[
            r#"{"alphaMode": "BLEND", "pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 0.3]}}"#,
            r#"{"alphaMode": "MASK", "alphaCutoff": 0.2, "pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 0.3]}}"#,
        ],
        "",
    );
    assert_eq!(fixture.warnings(&loaded), Vec::<String>::new());
    let m = &loaded.description.materials;
    let blend = m[0].cutout().unwrap();
    assert!(blend.blend);
    assert!(close(blend.coverage(TOP_LEFT), 0.3));
    let mask = m[1].cutout().unwrap();
    assert!(!mask.blend);
    assert_eq!(mask.cutoff, 0.2);
    assert_eq!(mask.coverage(TOP_LEFT), 1.0);
}

/// Full mode (the command line's default) composites a blended triangle over the
/// backdrop rather than dithering it at its one ray a pixel: across the middle row,
/// every pixel between the triangle's edges shows it, half the backdrop showing
/// through, and neighbours differ by at most a few levels.
#[test]
fn full_mode_shows_a_blended_surface_without_dither() {
    let fixture = Fixture::new();
    let veil = fixture.gltf(
        "veil",
        &[r#"{"alphaMode": "BLEND", "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.2, 0.1, 0.5]}}"#],
        "",
    );
    let (width, height) = (80, 60);
    // One ray a pixel (the rig's default is four, which would blend the edges).
    let rgb = render(
        &veil,
        &fixture.0.path().join("veil.png"),
        &["--width", "80", "--height", "60", "--spp", "1"],
    );
    let red = |x: usize| i32::from(rgb[3 * (height / 2 * width + x)]);
    let backdrop = red(0);
    let covered: Vec<usize> = (0..width).filter(|&x| red(x) != backdrop).collect();
    let (first, last) = (covered[0], *covered.last().unwrap());
    assert!(
        last - first > width / 4,
        "the triangle spans {first}..={last}"
    );
    for x in first + 1..last {
        assert!(
            red(x) > backdrop + 20,
            "pixel {x}: {} over {backdrop}",
            red(x)
        );
        assert!(
            (red(x) - red(x + 1)).abs() <= 3,
            "pixels {x}, {}: {} and {}",
            x + 1,
            red(x),
            red(x + 1)
        );
    }
}

#[test]
fn gltf_extensions_land_in_the_material() {
    let fixture = Fixture::new();
    let loaded = fixture.load(
        &[
            r#"{"name": "ior", "extensions": {"KHR_materials_ior": {"ior": 1.33}}}"#,
            r#"{"name": "specular", "extensions": {"KHR_materials_specular": {"specularFactor": 0.5,
                "specularTexture": {"index": 0}, "specularColorFactor": [1, 0.5, 0.25],
                "specularColorTexture": {"index": 0}}}}"#,
            r#"{"name": "glass", "extensions": {"KHR_materials_transmission": {"transmissionFactor": 0.9,
                "transmissionTexture": {"index": 0}},
                "KHR_materials_volume": {"thicknessFactor": 0.1, "attenuationColor": [0.5, 0.8, 1], "attenuationDistance": 2}}}"#,
            r#"{"name": "coat", "extensions": {"KHR_materials_clearcoat": {"clearcoatFactor": 0.7,
                "clearcoatTexture": {"index": 0}, "clearcoatRoughnessFactor": 0.3,
                "clearcoatRoughnessTexture": {"index": 0},
                "clearcoatNormalTexture": {"index": 0, "scale": 0.5}}}}"#,
            r#"{"name": "velvet", "extensions": {"KHR_materials_sheen": {"sheenColorFactor": [0.9, 0.1, 0.2],
                "sheenColorTexture": {"index": 0}, "sheenRoughnessFactor": 0.6,
                "sheenRoughnessTexture": {"index": 0}}}}"#,
            r#"{"name": "lamp", "emissiveFactor": [1, 0.5, 0.25],
                "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 8}}}"#,
            r#"{"name": "moved", "pbrMetallicRoughness": {"metallicRoughnessTexture": {"index": 0,
                "extensions": {"KHR_texture_transform": {"scale": [2, 3]}}}},
                "normalTexture": {"index": 0, "extensions": {"KHR_texture_transform": {"scale": [4, 5]}}},
                "extensions": {"KHR_materials_sheen": {"sheenColorFactor": [1, 1, 1], "sheenColorTexture": {"index": 0,
                "extensions": {"KHR_texture_transform": {"scale": [6, 7]}}}}}}"#,
            r#"{"name": "brushed", "extensions": {"KHR_materials_anisotropy": {"anisotropyStrength": 0.6,
                "anisotropyRotation": 1.2, "anisotropyTexture": {"index": 0}}}}"#,
        ],
        r#""extensionsUsed": ["KHR_materials_ior", "KHR_materials_specular", "KHR_materials_transmission",
            "KHR_materials_volume", "KHR_materials_clearcoat", "KHR_materials_sheen", "KHR_materials_anisotropy",
            "KHR_materials_emissive_strength", "KHR_texture_transform"],
           "extensionsRequired": ["KHR_materials_volume", "KHR_materials_clearcoat"],"#,
    );
    assert_eq!(fixture.warnings(&loaded), Vec::<String>::new());
    let m = &loaded.description.materials;
    assert_eq!(pbr(&m[0]).ior, 1.33);
    assert_eq!(m[0].ior, 1.33);

    let specular = pbr(&m[1]);
    assert_eq!(specular.specular, 0.5);
    assert_eq!(specular.specular_color, Vec3::new(1.0, 0.5, 0.25));
    let values = m[1].pbr_at(TOP_RIGHT).unwrap();
    // specularTexture: alpha; specularColorTexture: sRGB colour.
    assert!(close(values.specular, 0.5 * unit(100)), "{values:?}");
    let colour = Vec3::new(
        srgb_to_linear(unit(20)),
        srgb_to_linear(unit(255)),
        srgb_to_linear(unit(0)),
    ) * Vec3::new(1.0, 0.5, 0.25);
    assert!(close3(values.specular_color, colour), "{values:?}");

    let glass = pbr(&m[2]);
    assert_eq!((glass.transmission, glass.thickness), (0.9, 0.1));
    assert_eq!(glass.attenuation_color, Vec3::new(0.5, 0.8, 1.0));
    assert_eq!(glass.attenuation_distance, 2.0);
    let values = m[2].pbr_at(TOP_RIGHT).unwrap();
    assert!(close(values.transmission, 0.9 * unit(20)), "{values:?}"); // red
    assert!(values.volume);

    let coat = pbr(&m[3]);
    assert_eq!((coat.clearcoat, coat.clearcoat_roughness), (0.7, 0.3));
    let values = m[3].pbr_at(TOP_LEFT).unwrap();
    assert!(close(values.clearcoat, 0.7 * unit(10)), "{values:?}"); // red
    assert!(
        close(values.clearcoat_roughness, 0.3 * unit(64)),
        "{values:?}"
    ); // green
    let coat_normal = m[3].maps.as_deref().unwrap().pbr.clearcoat_normal.as_ref();
    assert_eq!(coat_normal.unwrap().options.bump_multiplier, 0.5);

    let velvet = pbr(&m[4]);
    assert_eq!(velvet.sheen_color, Vec3::new(0.9, 0.1, 0.2));
    assert_eq!(velvet.sheen_roughness, 0.6);
    let values = m[4].pbr_at(TOP_LEFT).unwrap();
    assert!(close(values.sheen_roughness, 0.6 * unit(200)), "{values:?}"); // alpha

    assert_eq!(m[5].emission, Vec3::new(8.0, 4.0, 2.0));

    // KHR_texture_transform on the metallic-roughness texture (both of its maps).
    let maps = m[6].maps.as_deref().unwrap();
    for map in [&maps.pbr.roughness, &maps.pbr.metallic] {
        assert_eq!(map.as_ref().unwrap().options.scale, Vec2::new(2.0, 3.0));
    }
    // And on the normal texture, and on an extension's texture.
    let normal = maps.normal.as_ref().unwrap();
    assert_eq!(normal.options.scale, Vec2::new(4.0, 5.0));
    let sheen = maps.pbr.sheen_color.as_ref().unwrap();
    assert_eq!(sheen.options.scale, Vec2::new(6.0, 7.0));

    // KHR_materials_anisotropy: the strength times the texture's blue (linear), the
    // direction its red and green in [-1, 1] turned by the rotation.
    let brushed = pbr(&m[7]);
    assert_eq!(
        (brushed.anisotropy, brushed.anisotropy_rotation),
        (0.6, 1.2)
    );
    let [r, g, b, _] = TEXELS[0];
    let values = m[7].pbr_at(TOP_LEFT).unwrap();
    assert!(close(values.anisotropy, 0.6 * unit(b)), "{values:?}");
    let maps = m[7].maps.as_deref().map(|m| &m.pbr);
    let direction = brushed.anisotropy_direction(TOP_LEFT, maps);
    let (x, y) = (2.0 * unit(r) - 1.0, 2.0 * unit(g) - 1.0);
    let turned = y.atan2(x) + 1.2;
    assert!(
        close(direction.x, turned.cos()) && close(direction.y, turned.sin()),
        "{direction}"
    );
}

#[test]
fn specular_glossiness_converts_as_blender_does() {
    let fixture = Fixture::new();
    let loaded = fixture.load(
        &[
            r#"{"name": "factors", "extensions": {"KHR_materials_pbrSpecularGlossiness": {
                "diffuseFactor": [0.5, 0.4, 0.3, 1], "specularFactor": [0.2, 0.3, 0.4], "glossinessFactor": 0.7}}}"#,
            r#"{"name": "textured", "extensions": {"KHR_materials_pbrSpecularGlossiness": {
                "diffuseTexture": {"index": 0}, "glossinessFactor": 0.5,
                "specularGlossinessTexture": {"index": 0}}}}"#,
        ],
        r#""extensionsUsed": ["KHR_materials_pbrSpecularGlossiness"],"#,
    );
    assert!(
        fixture.warnings(&loaded).is_empty(),
        "{:?}",
        loaded.description.warnings
    );
    let m = &loaded.description.materials;
    let factors = pbr(&m[0]);
    assert_eq!(factors.base_color, Vec3::new(0.5, 0.4, 0.3));
    assert_eq!(factors.metallic, 0.0);
    assert!(close(factors.roughness, 0.3));
    // Reflectance at normal incidence is the specular colour, within Fresnel 0.996.
    let f0 = m[0].pbr_at(Vec2::ZERO).unwrap().dielectric_f0();
    assert!(
        (f0 - Vec3::new(0.2, 0.3, 0.4)).abs().max_element() < 0.002,
        "{f0}"
    );
    for (uv, texel) in [(TOP_LEFT, 0), (TOP_RIGHT, 1), (BOTTOM_RIGHT, 3)] {
        let values = m[1].pbr_at(uv).unwrap();
        let [r, g, b, a] = TEXELS[texel];
        assert!(
            close(values.roughness, 1.0 - 0.5 * unit(a)),
            "{uv}: {values:?}"
        );
        let colour = Vec3::new(
            srgb_to_linear(unit(r)),
            srgb_to_linear(unit(g)),
            srgb_to_linear(unit(b)),
        );
        assert!(close3(values.specular_color, colour), "{uv}: {values:?}");
        assert!(close3(values.base_color, colour), "{uv}: {values:?}");
        assert_eq!(values.metallic, 0.0);
    }
}

#[test]
fn unknown_extensions_warn_and_unsupported_required_ones_are_errors() {
    let fixture = Fixture::new();
    let loaded = fixture.load(
        &[r#"{"name": "a"}"#],
        r#""extensionsUsed": ["KHR_materials_iridescence", "EXT_lights_image_based", "KHR_texture_transform"],"#,
    );
    assert_eq!(
        fixture.warnings(&loaded),
        [
            "extension KHR_materials_iridescence is not supported; the file is read without it",
            "extension EXT_lights_image_based is not supported; the file is read without it",
        ]
    );
    for required in ["KHR_materials_iridescence", "EXT_lights_image_based"] {
        let path = fixture.gltf(
            "required",
            &[r#"{"name": "a"}"#],
            &format!(r#""extensionsUsed": ["{required}"], "extensionsRequired": ["{required}"],"#),
        );
        let error = formats::load(&path).unwrap_err().to_string();
        assert_eq!(
            error,
            format!(
                "{}: the file requires extension {required}, which this renderer does not support",
                path.display()
            )
        );
    }
}

#[test]
fn bad_gltf_values_get_one_warning_per_kind() {
    let fixture = Fixture::new();
    let loaded = fixture.load(
        &[
            r#"{"name": "a", "pbrMetallicRoughness": {"roughnessFactor": 2, "metallicFactor": -1}}"#,
            r#"{"name": "b", "pbrMetallicRoughness": {"roughnessFactor": -0.5}}"#,
            r#"{"name": "c", "pbrMetallicRoughness": {"roughnessFactor": 1.5},
                "extensions": {"KHR_materials_ior": {"ior": 0.5}}}"#,
            r#"{"name": "d", "pbrMetallicRoughness": {"roughnessFactor": 9},
                "extensions": {"KHR_materials_volume": {"thicknessFactor": 1, "attenuationDistance": 0}}}"#,
            r#"{"name": "zero", "extensions": {"KHR_materials_ior": {"ior": 0}}}"#,
            r#"{"name": "flat", "normalTexture": {"index": 1}}"#,
            r#"{"name": "greyscale", "pbrMetallicRoughness": {"metallicRoughnessTexture": {"index": 1}}}"#,
        ],
        "",
    );
    assert_eq!(
        fixture.warnings(&loaded),
        [
            "material 'a': metallic outside [0, 1], clamped",
            "4 materials ('a', 'b', 'c', ...): roughness outside [0, 1], clamped",
            "material 'c': ior below 1, read as 1",
            "material 'd': attenuation distance of 0 or less, read as infinite (no attenuation)",
            "material 'zero': ior 0 (a Fresnel reflectance of 1) read as ior 1000",
            "material 'flat': a normal texture of fewer than 3 channels, ignored",
        ]
    );
    let m = &loaded.description.materials;
    assert_eq!((pbr(&m[0]).roughness, pbr(&m[0]).metallic), (1.0, 0.0));
    assert_eq!(pbr(&m[1]).roughness, 0.0);
    assert_eq!(pbr(&m[2]).ior, 1.0);
    assert_eq!(pbr(&m[3]).attenuation_distance, Float::INFINITY);
    assert_eq!(pbr(&m[4]).ior, 1000.0);
    assert!(m[5].maps.is_none());
    // A greyscale metallic-roughness texture is read: its grey for both.
    let values = m[6].pbr_at(TOP_RIGHT).unwrap();
    assert!(close(values.roughness, unit(85)) && close(values.metallic, unit(85)));
}

#[test]
fn a_default_metal_whose_texture_says_dielectric_does_not_render_black() {
    // metallicFactor is left at 1; the texture's blue (metallic) is 0 everywhere.
    let fixture = Fixture::new();
    write_png(
        &fixture.0.path().join("dielectric.png"),
        1,
        1,
        3,
        &[0, 128, 0],
    );
    let path = fixture.gltf(
        "controller",
        &[
            r#"{"name": "plastic", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1],
            "metallicRoughnessTexture": {"index": 2}}}"#,
        ],
        r#""samplers": [], "#,
    );
    // Texture 2 is the new image.
    let json = std::fs::read_to_string(&path).unwrap().replace(
        r#""images": [{"uri": "rgba.png"}, {"uri": "grey.png"}],
  "textures": [{"source": 0}, {"source": 1}],"#,
        r#""images": [{"uri": "rgba.png"}, {"uri": "grey.png"}, {"uri": "dielectric.png"}],
  "textures": [{"source": 0}, {"source": 1}, {"source": 2}],"#,
    );
    std::fs::write(&path, json).unwrap();
    let loaded = formats::load(&path).unwrap();
    let material = &loaded.description.materials[0];
    let values = material.pbr_at(Vec2::new(0.5, 0.5)).unwrap();
    assert_eq!(values.metallic, 0.0);
    // Full mode's Phong approximation at that point: a grey diffuse.
    let phong = material.at(Vec2::new(0.5, 0.5));
    assert!(phong.diffuse.min_element() > 0.7, "{phong:?}");

    for mode in ["full", "path"] {
        let out = fixture.0.path().join(format!("{mode}.png"));
        let output = Command::new(env!("CARGO_BIN_EXE_raytracer"))
            .args(["render", path.to_str().unwrap(), "-o"])
            .arg(&out)
            .args(["--width", "24", "--height", "24", "--mode", mode])
            .args(if mode == "path" {
                &["--spp", "4"][..]
            } else {
                &[][..]
            })
            .output()
            .unwrap();
        assert!(
            output.status.success(),
            "{}",
            String::from_utf8_lossy(&output.stderr)
        );
        let decoder =
            png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&out).unwrap()));
        let mut reader = decoder.read_info().unwrap();
        let mut pixels = vec![0; reader.output_buffer_size().unwrap()];
        reader.next_frame(&mut pixels).unwrap();
        // The triangle covers the middle of the image: it is lit there.
        let middle = (12 * 24 + 12) * 3;
        assert!(
            pixels[middle..middle + 3].iter().all(|&c| c > 40),
            "{mode}: the middle pixel is {:?}",
            &pixels[middle..middle + 3]
        );
    }
}

/// The materials and warnings of an MTL file's text (textures beside it).
fn mtl(text: &str, dir: &Path) -> formats::MaterialLibrary {
    let path = dir.join("m.mtl");
    std::fs::write(&path, text).unwrap();
    formats::parse_mtl(text.as_bytes(), &path).unwrap()
}

#[test]
fn mtl_pbr_statements_make_a_physically_based_material_and_others_stay_phong() {
    let fixture = Fixture::new();
    let dir = fixture.0.path();
    // A flat tangent-space normal map, as Blender writes through `map_Bump`.
    write_png(&dir.join("normal.png"), 1, 1, 3, &[128, 128, 255]);
    let library = mtl(
        "newmtl phong\nKa 1 1 1\nKd 0.8 0.1 0.1\nKs 0.5 0.5 0.5\nNs 250\nNi 1.45\nmap_Kd rgba.png\n\
         newmtl blender\nNs 250\nKa 1 1 1\nKd 0.8 0.1 0.1\nKs 0.5 0.5 0.5\nKe 4 2 0\nNi 1.45\nd 1\nillum 2\n\
         Pr 0.5\nPm 0.25\nPs 0.3\nPc 0.6\nPcr 0.2\naniso 0.1\nanisor 0.5\nTf 0.4 0.4 0.4\n\
         map_Kd rgba.png\nmap_Bump -bm 0.5 normal.png\n\
         newmtl mapped\nKd 1 1 1\nmap_Pr -imfchan g rgba.png\nmap_Pm -imfchan b rgba.png\nNs 1000\n\
         newmtl from_ns\nKd 1 1 1\nPm 1\nNs 250\n\
         newmtl bad\nPr 1.5\nPm -0.5\nNi 0.5\naniso 1.5\n",
        dir,
    );
    let path = dir.join("m.mtl");
    let m = &library.materials;
    // No PBR statement: exactly the Phong material.
    assert!(m[0].pbr.is_none());
    assert_eq!(m[0].ambient, Vec3::ONE);
    assert_eq!(m[0].shininess, 250.0);
    assert!(m[0].maps.as_ref().unwrap().diffuse.is_some());

    let blender = pbr(&m[1]);
    assert_eq!(blender.base_color, Vec3::new(0.8, 0.1, 0.1));
    assert_eq!((blender.roughness, blender.metallic), (0.5, 0.25));
    assert_eq!(blender.ior, 1.45);
    assert_eq!(blender.specular, 1.0); // twice Blender's Specular 0.5
    assert!(close(blender.transmission, 0.4));
    assert_eq!((blender.clearcoat, blender.clearcoat_roughness), (0.6, 0.2));
    assert_eq!(blender.sheen_color, Vec3::splat(0.3));
    // `aniso` the strength, `anisor` in turns (Blender's Anisotropic Rotation).
    assert_eq!(blender.anisotropy, 0.1);
    assert!(close(blender.anisotropy_rotation, std::f32::consts::PI));
    assert_eq!(m[1].emission, Vec3::new(4.0, 2.0, 0.0)); // Ke above 1
    assert_eq!(m[1].ambient, Vec3::ZERO); // Blender's Ka is its metallic
    let maps = m[1].maps.as_deref().unwrap();
    assert!(maps.diffuse.is_none() && maps.pbr.base_color.is_some());
    // Blender's normal map through map_Bump, with its strength.
    assert_eq!(maps.normal.as_ref().unwrap().options.bump_multiplier, 0.5);

    // A map alone means a factor of 1.
    let mapped = pbr(&m[2]);
    assert_eq!((mapped.roughness, mapped.metallic), (1.0, 1.0));
    let values = m[2].pbr_at(TOP_LEFT).unwrap();
    assert!(close(values.roughness, unit(64)) && close(values.metallic, unit(255)));

    // Without Pr, roughness inverts Blender's Ns = 1000 (1 - roughness)^2.
    assert!(close(pbr(&m[3]).roughness, 0.5));
    assert_eq!(pbr(&m[3]).metallic, 1.0);

    let bad = pbr(&m[4]);
    assert_eq!((bad.roughness, bad.metallic, bad.ior), (1.0, 0.0, 1.0));
    assert_eq!(bad.anisotropy, 1.0);
    let p = path.display();
    assert_eq!(
        library.warnings,
        [
            format!("{p}: material 'bad': metallic outside [0, 1], clamped"),
            format!("{p}: material 'bad': roughness outside [0, 1], clamped"),
            format!("{p}: material 'bad': anisotropy outside [0, 1], clamped"),
            format!("{p}: material 'bad': ior below 1, read as 1"),
        ]
    );
}

#[test]
fn toml_physically_based_keys() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.toml");
    let text = r#"
[materials.plastic]
base_color = [0.8, 0.2, 0.1]

[materials.everything]
base_color = 0.5
metallic = 0.7
roughness = 0.3
ior = 1.33
specular = 0.5
specular_color = [1, 0.5, 0.25]
transmission = 0.9
thickness = 1
attenuation_color = [0.5, 0.6, 0.7]
attenuation_distance = 2
clearcoat = 0.4
clearcoat_roughness = 0.2
sheen_color = [0.1, 0.2, 0.3]
sheen_roughness = 0.6
multiple_scattering = true
anisotropy = 0.6
anisotropy_rotation = 1.5
emission = [1, 0.5, 0]
emission_strength = 4

[materials.mixed]
Kd = 0.5
Ks = 0.5
Ke = 2
Ni = 1.2
roughness = 0.5

[materials.bad]
roughness = 2
attenuation_distance = 0
metallic = nan
anisotropy = nan
anisotropy_rotation = inf

[materials.phong]
Kd = 0.5
"#;
    std::fs::write(&path, text).unwrap();
    let loaded = formats::load(&path).unwrap();
    let m = &loaded.description.materials;
    let plastic = pbr(&m[0]);
    assert_eq!(plastic.base_color, Vec3::new(0.8, 0.2, 0.1));
    assert_eq!(plastic.metallic, 0.0); // not glTF's 1
    assert_eq!(plastic.roughness, 1.0);

    let e = pbr(&m[1]);
    assert_eq!(e.base_color, Vec3::splat(0.5));
    assert_eq!(
        (e.metallic, e.roughness, e.ior, e.specular),
        (0.7, 0.3, 1.33, 0.5)
    );
    assert_eq!(e.specular_color, Vec3::new(1.0, 0.5, 0.25));
    assert_eq!((e.transmission, e.thickness), (0.9, 1.0));
    assert_eq!(e.attenuation_color, Vec3::new(0.5, 0.6, 0.7));
    assert_eq!(e.attenuation_distance, 2.0);
    assert_eq!((e.clearcoat, e.clearcoat_roughness), (0.4, 0.2));
    assert_eq!(e.sheen_color, Vec3::new(0.1, 0.2, 0.3));
    assert_eq!(e.sheen_roughness, 0.6);
    assert!(e.multiple_scattering && !plastic.multiple_scattering);
    assert_eq!((e.anisotropy, e.anisotropy_rotation), (0.6, 1.5));
    // Anisotropic: the readers and the scene keep texture coordinates for its
    // tangents, though it has no maps.
    assert!(m[1].needs_texcoords() && m[1].maps.is_none() && !m[0].needs_texcoords());
    assert_eq!(m[1].emission, Vec3::new(4.0, 2.0, 0.0));

    // Ke and Ni stand for emission and ior; Kd and Ks are ignored.
    let mixed = pbr(&m[2]);
    assert_eq!((mixed.ior, mixed.roughness), (1.2, 0.5));
    assert_eq!(mixed.base_color, Vec3::ONE);
    assert_eq!(m[2].emission, Vec3::splat(2.0));

    let bad = pbr(&m[3]);
    assert_eq!((bad.roughness, bad.metallic), (1.0, 0.0));
    assert_eq!(bad.attenuation_distance, Float::INFINITY);
    assert_eq!((bad.anisotropy, bad.anisotropy_rotation), (0.0, 0.0));

    assert!(m[4].pbr.is_none());
    assert_eq!(m[4].diffuse, Vec3::splat(0.5));

    let p = path.display();
    assert_eq!(
        loaded.description.warnings,
        [
            format!(
                "{p}: material 'mixed': MTL keys (Kd, Ks) beside physically based keys are ignored"
            ),
            format!("{p}: material 'bad': metallic is NaN, read as 0"),
            format!("{p}: material 'bad': roughness outside [0, 1], clamped"),
            format!("{p}: material 'bad': anisotropy is NaN, read as 0"),
            format!("{p}: material 'bad': anisotropy rotation is not finite, read as 0"),
            format!(
                "{p}: material 'bad': attenuation distance of 0 or less, read as infinite (no attenuation)"
            ),
        ]
    );
}

#[test]
fn full_mode_shows_a_fully_rough_metal_as_a_diffuser_not_a_black_mirror() {
    // glTF's defaults (metallic 1, roughness 1) make such a metal: it scatters as
    // broadly as a rough plastic of its colour, so full mode's default rig must light
    // it as it lights that plastic, with no black rim around a highlight.
    let fixture = Fixture::new();
    let scene = |name: &str, metallic: u32| {
        let path = fixture.0.path().join(format!("{name}.toml"));
        let toml = format!(
            "[[sphere]]\ncenter = [0, 0, 0]\nradius = 1\nmaterial = \"m\"\n\
             [materials.m]\nbase_color = 0.8\nmetallic = {metallic}\nroughness = 1\n"
        );
        std::fs::write(&path, toml).unwrap();
        path
    };
    let (metal, plastic) = (scene("metal", 1), scene("plastic", 0));
    let size = ["--width", "40", "--height", "40"];
    let out = |name: &str| fixture.0.path().join(format!("{name}.png"));
    let normals = render(
        &metal,
        &out("normal"),
        &[&size[..], &["--mode", "normal"]].concat(),
    );
    let metal = render(&metal, &out("metal"), &size);
    let plastic = render(&plastic, &out("plastic"), &size);
    let hit = |x: usize, y: usize| normals[(y * 40 + x) * 3..][..3].iter().any(|&c| c > 0);
    let brightness =
        |image: &[u8], i: usize| image[i * 3..][..3].iter().map(|&c| c as u32).sum::<u32>();
    let mut inner = 0;
    for y in 1..39 {
        for x in 1..39 {
            // Inside the disc, away from its anti-aliased rim.
            if !(hit(x, y) && hit(x - 1, y) && hit(x + 1, y) && hit(x, y - 1) && hit(x, y + 1)) {
                continue;
            }
            inner += 1;
            let (m, p) = (
                brightness(&metal, y * 40 + x),
                brightness(&plastic, y * 40 + x),
            );
            assert!(10 * m >= 8 * p, "pixel ({x}, {y}): metal {m}, plastic {p}");
        }
    }
    assert!(inner > 400, "the sphere covers {inner} inner pixels");
}
