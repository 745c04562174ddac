//! The extensions that give a texture an image in another format, named in the
//! extension's `source`, its core `source` (if any) being a PNG or JPEG fallback for
//! viewers without that format:
//! - `EXT_texture_webp`: WebP (lossy and lossless), decoded by the `image` crate;
//! - `KHR_texture_basisu`: KTX2 of Basis Universal texels (ETC1S or UASTC, zstd
//!   supercompression or none), transcoded to RGBA by the `basisu` crate
//!   ([`crate::textures::Texture::decode`]).
//!
//! The extension's image is read, as a viewer that knows the format shows it; if it
//! cannot be read or decoded, the core image is, with a warning, and without one the
//! surface renders without the texture (a warning naming the file and image, as for
//! any image).

use std::collections::HashMap;

use gltf::json::{Index, Root, Value};

/// `EXT_texture_webp`'s name.
pub(in crate::formats::gltf) const WEBP: &str = "EXT_texture_webp";
/// `KHR_texture_basisu`'s name.
pub(in crate::formats::gltf) const BASISU: &str = "KHR_texture_basisu";
/// Both, in the order their sources are taken: a texture that has both reads the
/// last one's image.
pub(in crate::formats::gltf) const NAMES: [&str; 2] = [WEBP, BASISU];

/// Points each texture that has one of the extensions (`objects`: the extension's
/// name and object, by texture index) at the extension's image, so that the `gltf`
/// crate, which knows nothing of them, reads that image (and validates a texture
/// whose core `source` is absent). Returns the core image each such texture had, by
/// texture index (its fallback), and a warning for each extension object whose
/// `source` is not an image of the file (that texture keeps its source).
pub(in crate::formats::gltf) fn use_extension_sources(
    root: &mut Root,
    objects: &[(usize, &'static str, Value)],
) -> (HashMap<usize, usize>, Vec<String>) {
    let mut fallbacks = HashMap::new();
    let mut warnings = Vec::new();
    let images = root.images.len();
    for (index, name, extension) in objects {
        let Some(texture) = root.textures.get_mut(*index) else {
            continue;
        };
        let source = extension
            .get("source")
            .and_then(Value::as_u64)
            .and_then(|s| usize::try_from(s).ok())
            .filter(|&s| s < images);
        let Some(source) = source else {
            warnings.push(format!(
                "texture {index}: its {name} 'source' is not an image of the file; its core source is read"
            ));
            continue;
        };
        let core = texture.source.value();
        if core < images && core != source {
            // A texture with both extensions falls back to its core image.
            fallbacks.entry(*index).or_insert(core);
        }
        texture.source = Index::new(source as u32);
    }
    (fallbacks, warnings)
}
