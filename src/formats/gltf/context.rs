//! The glTF material being read ([`MaterialContext`]): what the core model and each
//! extension in [`super::extensions`] have set so far, and how they read values and
//! texture references from the material's JSON. Apart from `material.rs`, so that the
//! extensions and the core model both import it without importing each other.

use gltf::json::Value;

use super::Reader;
use super::extensions::texture_transform;
use crate::material::pbr::PbrMaterial;
use crate::material::{Cutout, MaterialMaps};
use crate::math::{Float, Vec3};
use crate::textures::{Channel, TextureMap};

/// A glTF material being read: what the core and each extension have set so far.
pub(super) struct MaterialContext<'r, 'a> {
    pub(super) reader: &'r mut Reader<'a>,
    /// Its name (`material3` when it has none).
    pub(super) name: String,
    pub(super) pbr: PbrMaterial,
    pub(super) maps: MaterialMaps,
    /// `emissiveFactor`.
    pub(super) emission: Vec3,
    /// `KHR_materials_emissive_strength`: multiplies `emission`.
    pub(super) emission_strength: Float,
    /// The base colour's alpha factor.
    pub(super) alpha: Float,
    /// The texture whose alpha is the base colour's alpha.
    pub(super) alpha_map: Option<TextureMap>,
}

/// `map` reading `channel`.
pub(super) fn with_channel(map: &TextureMap, channel: Channel) -> TextureMap {
    let mut map = map.clone();
    map.options.channel = channel;
    map
}

impl MaterialContext<'_, '_> {
    /// Notes a problem of this material (one warning per kind, naming the materials).
    pub(super) fn note(&mut self, kind: impl Into<String>) {
        self.reader.problems.note(kind, &self.name);
    }

    /// Number `key` of `object`, `default` when absent; one that is not a number is
    /// noted and read as `default`.
    pub(super) fn number(&mut self, object: &Value, key: &str, default: Float) -> Float {
        match object.get(key) {
            None => default,
            Some(value) => match value.as_f64() {
                Some(v) if (v as Float).is_finite() => v as Float,
                _ => {
                    self.note(format!("'{key}' is not a finite number, read as {default}"));
                    default
                }
            },
        }
    }

    /// `N` numbers under `key`, `default` when absent; anything else is noted and
    /// read as `default`.
    pub(super) fn numbers<const N: usize>(
        &mut self,
        object: &Value,
        key: &str,
        default: [Float; N],
    ) -> [Float; N] {
        let Some(value) = object.get(key) else {
            return default;
        };
        let read = value.as_array().filter(|a| a.len() == N).and_then(|a| {
            let mut out = default;
            for (o, v) in out.iter_mut().zip(a) {
                *o = v.as_f64().map(|v| v as Float).filter(|v| v.is_finite())?;
            }
            Some(out)
        });
        read.unwrap_or_else(|| {
            self.note(format!(
                "'{key}' is not {N} finite numbers, read as the default"
            ));
            default
        })
    }

    /// An RGB colour under `key`.
    pub(super) fn colour(&mut self, object: &Value, key: &str, default: Vec3) -> Vec3 {
        Vec3::from(self.numbers(object, key, default.to_array()))
    }

    /// An RGBA colour under `key`.
    pub(super) fn colour4(&mut self, object: &Value, key: &str, default: [Float; 4]) -> [Float; 4] {
        self.numbers(object, key, default)
    }

    /// The normal map of texture reference `key` of `object` (a glTF
    /// `normalTextureInfo`), its `scale`, which multiplies the tangent-space normal's
    /// x and y, kept as the map's `bump_multiplier`; one of fewer than 3 channels is
    /// noted (as `what`) and ignored.
    pub(super) fn normal_texture(
        &mut self,
        object: &Value,
        key: &str,
        what: &str,
    ) -> Option<TextureMap> {
        let mut map = self.texture(object, key)?;
        if map.texture.channels() < 3 {
            self.note(format!("{what} of fewer than 3 channels, ignored"));
            return None;
        }
        map.options.bump_multiplier = object
            .get(key)
            .map_or(1.0, |info| self.number(info, "scale", 1.0));
        Some(map)
    }

    /// The map of texture reference `key` of `object` (a glTF `textureInfo`: `index`
    /// and `KHR_texture_transform`), if there is one and its image can be read (else
    /// a warning).
    pub(super) fn texture(&mut self, object: &Value, key: &str) -> Option<TextureMap> {
        let info = object.get(key)?;
        let document = self.reader.document;
        let Some(texture) = info
            .get("index")
            .and_then(Value::as_u64)
            .and_then(|i| document.textures().nth(usize::try_from(i).ok()?))
        else {
            self.note(format!("'{key}' names no texture of the file, ignored"));
            return None;
        };
        let transform = info
            .get("extensions")
            .and_then(|e| e.get(texture_transform::NAME));
        // Its `texCoord` is its material's (`material::texcoord_sets`), read by the
        // mesh reader.
        let mut map = self.reader.texture_map(&texture)?;
        if let Some(transform) = transform {
            let offset = self.numbers(transform, "offset", [0.0, 0.0]);
            let rotation = self.number(transform, "rotation", 0.0);
            let scale = self.numbers(transform, "scale", [1.0, 1.0]);
            match texture_transform::texture_options(offset, rotation, scale) {
                Some((scale, rotation, offset)) => {
                    map.options.scale = scale;
                    map.options.rotation = rotation;
                    map.options.offset = offset;
                }
                None => self.note("a texture transform that is not finite, ignored"),
            }
        }
        Some(map)
    }

    /// A scalar texture reference read from `channel`.
    pub(super) fn scalar_texture(
        &mut self,
        object: &Value,
        key: &str,
        channel: Channel,
    ) -> Option<TextureMap> {
        let mut map = self.texture(object, key)?;
        map.options.channel = channel;
        Some(map)
    }

    /// `alphaMode` and `alphaCutoff`: MASK cuts the surface out where alpha is below
    /// the cutoff; BLEND lets a fraction `1 - alpha` of the rays through
    /// (stochastic transparency, [`Cutout::blend`]).
    pub(super) fn alpha_mode(&mut self, json: &Value) {
        let mode = json
            .get("alphaMode")
            .and_then(Value::as_str)
            .unwrap_or("OPAQUE");
        let (cutoff, blend) = match mode {
            "OPAQUE" => return,
            "MASK" => (self.number(json, "alphaCutoff", 0.5), false),
            "BLEND" => (0.5, true),
            other => {
                self.note(format!("unknown alphaMode '{other}', read as OPAQUE"));
                return;
            }
        };
        let map = self
            .alpha_map
            .as_ref()
            .map(|map| with_channel(map, Channel::Alpha));
        self.maps.cutout = Some(Cutout {
            map,
            factor: self.alpha,
            cutoff,
            blend,
        });
    }
}
