//! `EXT_texture_webp`: a texture whose image is a WebP file names it in the
//! extension's `source`; its core `source`, if any, is a PNG or JPEG fallback for
//! viewers without WebP. The extension's image is read (the `image` crate decodes
//! WebP, lossy and lossless); if it cannot be read or decoded, the core image is, with
//! a warning, and without one the surface renders without the texture (a warning
//! naming the file and image, as for any image).

use std::collections::HashMap;

use gltf::json::{Index, Root, Value};

pub(in crate::formats::gltf) const NAME: &str = "EXT_texture_webp";

/// Points each texture that has the extension (`webp`: its object, by texture
/// index) at its WebP image, so that the `gltf` crate, which knows nothing of it,
/// reads that image (and validates a texture whose core `source` is absent).
/// Returns the core image each such texture had, by texture index (its fallback),
/// and a warning for each extension object whose `source` is not an image of the
/// file (that texture keeps its core source).
pub(in crate::formats::gltf) fn use_webp_sources(
    root: &mut Root,
    webp: &[(usize, Value)],
) -> (HashMap<usize, usize>, Vec<String>) {
    let mut fallbacks = HashMap::new();
    let mut warnings = Vec::new();
    let images = root.images.len();
    for (index, extension) in webp {
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
                "texture {index}: its {NAME} 'source' is not an image of the file; its core source is read"
            ));
            continue;
        };
        let core = texture.source.value();
        if core < images && core != source {
            fallbacks.insert(*index, core);
        }
        texture.source = Index::new(source as u32);
    }
    (fallbacks, warnings)
}
