//! glTF materials: the core metallic-roughness model (`pbrMetallicRoughness`, the
//! normal, emissive and occlusion textures, alpha modes) as a
//! [`Material::physically_based`], with each `KHR_materials_*` extension applied by
//! its file in [`super::extensions`]. Materials are read from the file's own JSON,
//! so that every extension (the `gltf` crate has no types for clearcoat and sheen)
//! and every texture reference (`KHR_texture_transform` included) is read the same
//! way. `docs/scene-format.md` documents the mapping.

use std::sync::Arc;

use gltf::json::Value;

use super::context::{MaterialContext, with_channel};
use super::extensions::MATERIAL_EXTENSIONS;
use super::{Reader, file_of_uri, read_uri};
use crate::formats::material_check::check_pbr;
use crate::material::pbr::PbrMaterial;
use crate::material::{Material, MaterialMaps};
use crate::math::Vec3;
use crate::textures::{Channel, Texture, TextureMap, TextureOptions, Wrap, load_texture};

/// Converts glTF material `index` (its JSON object `json`) into a physically based
/// material.
pub(super) fn convert(reader: &mut Reader<'_>, index: usize, json: &Value) -> Material {
    let name = json
        .get("name")
        .and_then(Value::as_str)
        .map_or_else(|| format!("material{index}"), str::to_owned);
    let mut cx = MaterialContext {
        reader,
        index,
        name,
        pbr: PbrMaterial::default(),
        maps: MaterialMaps::default(),
        emission: Vec3::ZERO,
        emission_strength: 1.0,
        alpha: 1.0,
        alpha_map: None,
    };
    let empty = Value::Object(Default::default());
    let core = json.get("pbrMetallicRoughness").unwrap_or(&empty);
    let [r, g, b, a] = cx.colour4(core, "baseColorFactor", [1.0; 4]);
    cx.pbr.base_color = Vec3::new(r, g, b);
    cx.alpha = a;
    cx.pbr.metallic = cx.number(core, "metallicFactor", 1.0);
    cx.pbr.roughness = cx.number(core, "roughnessFactor", 1.0);
    // Base colour: sRGB, into the physically based maps only (the Phong
    // approximation reads it from there; `MaterialMaps::diffuse` would multiply it
    // twice).
    let base = cx.texture(core, "baseColorTexture");
    cx.alpha_map.clone_from(&base);
    cx.maps.pbr.base_color = base;
    // One image, two maps: roughness from green, metallic from blue. A greyscale
    // image reads its grey for both.
    if let Some(map) = cx.texture(core, "metallicRoughnessTexture") {
        cx.maps.pbr.roughness = Some(with_channel(&map, Channel::Green));
        cx.maps.pbr.metallic = Some(with_channel(&map, Channel::Blue));
    }
    cx.maps.normal = cx.normal_texture(json, "normalTexture", "a normal texture");
    cx.emission = cx.colour(json, "emissiveFactor", Vec3::ZERO);
    cx.maps.emission = cx.texture(json, "emissiveTexture");
    // `occlusionTexture` darkens indirect light in rasterisers; a path tracer traces
    // that light, so it is ignored (documented, not warned about).
    if let Some(used) = json.get("extensions").and_then(Value::as_object) {
        for extension in MATERIAL_EXTENSIONS {
            if let Some(value) = used.get(extension.name) {
                (extension.apply)(&mut cx, value);
            }
        }
    }
    cx.alpha_mode(json);
    let MaterialContext {
        reader,
        name,
        mut pbr,
        maps,
        emission,
        emission_strength,
        ..
    } = cx;
    check_pbr(
        &mut pbr,
        &PbrMaterial::default(),
        &name,
        &mut reader.problems,
    );
    let emission = emission * emission_strength;
    let emission = if emission.is_finite() && emission.min_element() >= 0.0 {
        emission
    } else {
        reader.problems.note(
            "an emission that is negative or not finite, read as 0",
            &name,
        );
        Vec3::ZERO
    };
    Material::physically_based(
        name,
        pbr,
        emission,
        (!maps.is_empty()).then(|| Box::new(maps)),
    )
}

impl Reader<'_> {
    /// The map of glTF texture `texture`, if its image can be read (else a warning).
    pub(super) fn texture_map(
        &mut self,
        texture: &gltf::Texture<'_>,
        tex_coord: u32,
        material: usize,
    ) -> Option<TextureMap> {
        if tex_coord != 0 {
            self.warn_once(
                "texcoord",
                format!(
                    "material {material}: only TEXCOORD_0 is read; a texture on TEXCOORD_{tex_coord} uses it instead"
                ),
            );
        }
        let image = texture.source();
        // `EXT_texture_webp`: the core image, if the WebP one cannot be read.
        let fallback = (self.webp_fallbacks.get(&texture.index()))
            .and_then(|&i| self.document.images().nth(i));
        let loaded = match self.image(&image, fallback.is_some()) {
            Some(loaded) => loaded,
            None => self.image(&fallback?, false)?,
        };
        let wrap = |mode| match mode {
            gltf::texture::WrappingMode::ClampToEdge => Wrap::Clamp,
            gltf::texture::WrappingMode::MirroredRepeat => Wrap::Mirror,
            gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
        };
        let sampler = texture.sampler();
        Some(TextureMap {
            texture: loaded,
            options: TextureOptions {
                wrap_u: wrap(sampler.wrap_s()),
                wrap_v: wrap(sampler.wrap_t()),
                ..TextureOptions::default()
            },
        })
    }

    /// Image `image`, decoded once; `None`, with a warning naming it (and, if
    /// `has_fallback`, what is read instead), if it cannot be read.
    fn image(&mut self, image: &gltf::Image<'_>, has_fallback: bool) -> Option<Arc<Texture>> {
        if let Some(loaded) = self.images.get(&image.index()) {
            return loaded.clone();
        }
        let loaded = match self.load_image(image) {
            Ok(texture) => Some(texture),
            Err(reason) => {
                let then = match has_fallback {
                    true => {
                        "the texture's core image (its EXT_texture_webp fallback) is read instead"
                    }
                    false => "the surface renders without it",
                };
                self.warn(format!("image {}: {reason}; {then}", image.index()));
                None
            }
        };
        self.images.insert(image.index(), loaded.clone());
        loaded
    }

    fn load_image(&self, image: &gltf::Image<'_>) -> Result<Arc<Texture>, String> {
        let name = self.path.with_file_name(format!(
            "{}#image{}",
            self.path.file_name().unwrap_or_default().to_string_lossy(),
            image.index()
        ));
        // `Image::source` unwraps a missing `uri` (with no `bufferView`) and a missing
        // `mimeType` (with one): the format is guessed from the bytes anyway.
        let json = &self.document.as_json().images[image.index()];
        if json.uri.is_none() && json.buffer_view.is_none() {
            return Err("names neither a file nor a buffer view".into());
        }
        if json.buffer_view.is_some() && json.mime_type.is_none() {
            return Err("has a buffer view but no mimeType".into());
        }
        match image.source() {
            gltf::image::Source::View { view, .. } => {
                let buffer = &self.buffers[view.buffer().index()];
                let bytes = view
                    .offset()
                    .checked_add(view.length())
                    .and_then(|end| buffer.get(view.offset()..end))
                    .ok_or("its buffer view lies outside its buffer")?;
                Texture::decode(bytes, &name)
                    .map(Arc::new)
                    .map_err(|e| format!("cannot decode: {e}"))
            }
            gltf::image::Source::Uri { uri, .. } if uri.starts_with("data:") => {
                let bytes = read_uri(uri, &self.folder, self.access)?;
                Texture::decode(&bytes, &name)
                    .map(Arc::new)
                    .map_err(|e| format!("cannot decode: {e}"))
            }
            gltf::image::Source::Uri { uri, .. } => {
                let file = file_of_uri(uri)?;
                let path = self.folder.join(&file);
                self.access
                    .admit(&path)
                    .map_err(|e| e.to_string())
                    .and_then(|()| load_texture(&path))
                    .map_err(|e| format!("cannot read texture '{}': {e}", file.display()))
            }
        }
    }
}
