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
use super::extensions::{MATERIAL_EXTENSIONS, texture_transform, unlit};
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

/// The texture coordinate set (`n` of `TEXCOORD_n`) each of the reader's materials
/// is read with, by material index: the set its textures name in their `texCoord`
/// (or their `KHR_texture_transform`'s), counting only the textures this reader
/// reads (not `occlusionTexture`, which often has a set of its own, nor those of
/// extensions it does not read; an unlit material's base colour alone). A scene
/// keeps one set of texture coordinates per primitive, so a material whose textures
/// name several sets is read with its base colour texture's (else the lowest), with
/// one warning for the file naming the first such material.
pub(super) fn texcoord_sets(reader: &mut Reader<'_>) -> Vec<u32> {
    let mut mixed = None;
    let sets = (reader.raw_materials.iter().enumerate())
        .map(|(index, json)| {
            let (base, mut sets) = texture_sets(json);
            sets.sort_unstable();
            sets.dedup();
            let set = base.or(sets.first().copied()).unwrap_or(0);
            if sets.len() > 1 && mixed.is_none() {
                mixed = Some((index, sets, set));
            }
            set
        })
        .collect();
    if let Some((index, sets, set)) = mixed {
        let names: Vec<String> = sets.iter().map(|s| format!("TEXCOORD_{s}")).collect();
        reader.warn_once(
            "texcoord",
            format!(
                "material {index}: its textures use {}, but one set is read per primitive: TEXCOORD_{set}, for all of them",
                names.join(" and ")
            ),
        );
    }
    sets
}

/// The set of material `json`'s base colour texture, if it has one, and the sets of
/// all the textures read (see [`texcoord_sets`]).
fn texture_sets(json: &Value) -> (Option<u32>, Vec<u32>) {
    let set = |info: &Value| -> u32 {
        let transform = (info.get("extensions")).and_then(|e| e.get(texture_transform::NAME));
        (transform.and_then(|t| t.get("texCoord")))
            .or_else(|| info.get("texCoord"))
            .and_then(Value::as_u64)
            .map_or(0, |s| u32::try_from(s).unwrap_or(u32::MAX))
    };
    let core = json.get("pbrMetallicRoughness");
    let base = core.and_then(|c| c.get("baseColorTexture")).map(set);
    let extensions = json.get("extensions").and_then(Value::as_object);
    if extensions.is_some_and(|e| e.contains_key(unlit::EXTENSION.name)) {
        return (base, base.into_iter().collect());
    }
    let mut sets: Vec<u32> = base.into_iter().collect();
    let objects = [core, Some(json)]
        .into_iter()
        .flatten()
        .chain((MATERIAL_EXTENSIONS.iter()).filter_map(|e| extensions.and_then(|x| x.get(e.name))));
    for object in objects {
        let Some(object) = object.as_object() else {
            continue;
        };
        for (key, info) in object {
            let texture = key.ends_with("Texture") && key != "occlusionTexture";
            if texture && key != "baseColorTexture" && info.get("index").is_some() {
                sets.push(set(info));
            }
        }
    }
    (base, sets)
}

impl Reader<'_> {
    /// The map of glTF texture `texture`, if its image can be read (else a warning).
    pub(super) fn texture_map(&mut self, texture: &gltf::Texture<'_>) -> Option<TextureMap> {
        let image = texture.source();
        // `EXT_texture_webp`, `KHR_texture_basisu`: the core image, if the
        // extension's cannot be read.
        let fallback = (self.image_fallbacks.get(&texture.index()))
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
                    true => "the texture's core image (its fallback) is read instead",
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
