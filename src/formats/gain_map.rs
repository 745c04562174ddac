//! JPEG images with an HDR gain map (Adobe's gain map, Google's Ultra HDR: an sRGB
//! image, then a second JPEG of log2 gains with its parameters in XMP), as viser and
//! three.js's `@monogrid/gainmap-js` ship Poly Haven's HDRIs: read at full HDR,
//! `HDR = (SDR + offset_sdr) * 2^(lerp(min, max, g^(1/gamma))) - offset_hdr`, each
//! base texel with the gain map's bilinear value at the same place. An environment
//! read as its SDR image alone is clipped at 1 (the sun and sky lose their range).

use std::path::Path;

use crate::textures::{Encoding, Texture, Wrap};

/// The gain map namespace, whose presence in the primary image's XMP marks the file.
const NAMESPACE: &[u8] = b"http://ns.adobe.com/hdr-gain-map/1.0/";

/// The HDR image of the JPEG file `bytes` whose SDR image is `base`, when the file
/// carries a gain map: `None` for another file; an error for a gain map that cannot
/// be read.
pub fn hdr_from_gain_map(
    bytes: &[u8],
    base: &Texture,
    path: &Path,
) -> Option<Result<Texture, String>> {
    if !bytes.starts_with(&[0xFF, 0xD8])
        || find(&bytes[..bytes.len().min(65_536)], NAMESPACE).is_none()
    {
        return None;
    }
    Some(read(bytes, base, path))
}

fn read(bytes: &[u8], base: &Texture, path: &Path) -> Result<Texture, String> {
    let start = gain_map_offset(bytes).ok_or("a gain map is announced but not found")?;
    let gain_bytes = &bytes[start..];
    let params = Params::from_xmp(gain_bytes)?;
    if params.base_is_hdr {
        return Err("a gain map whose base image is the HDR one is not read".into());
    }
    let gain = Texture::decode(gain_bytes, path).map_err(|e| format!("its gain map: {e}"))?;
    let (width, height) = base.size();
    let mut texels = Vec::with_capacity(width as usize * height as usize * 3);
    for y in 0..height as usize {
        for x in 0..width as usize {
            let sdr = base.texel(x, y, Encoding::Srgb);
            let uv = crate::math::Vec2::new(
                (x as f32 + 0.5) / width as f32,
                1.0 - (y as f32 + 0.5) / height as f32,
            );
            // The gain map's values are stored as they are, not sRGB-encoded.
            let g = gain.bilinear(uv, Wrap::Clamp, Wrap::Clamp, Encoding::Linear);
            for c in 0..3 {
                let g = if gain.channels() < 3 { g[0] } else { g[c] };
                let g = g.clamp(0.0, 1.0).powf(1.0 / params.gamma[c]);
                let log = params.min[c] * (1.0 - g) + params.max[c] * g;
                let hdr = (sdr[c] + params.offset_sdr[c]) * log.exp2() - params.offset_hdr[c];
                texels.push(hdr.max(0.0));
            }
        }
    }
    Texture::from_f32(path.to_path_buf(), width, height, 3, texels)
        .ok_or_else(|| "the HDR image does not fit a texture".into())
}

/// Where the gain map's JPEG begins: the second image of the primary's MPF index,
/// else the last item of its XMP container directory (Ultra HDR), whose length it
/// gives.
fn gain_map_offset(bytes: &[u8]) -> Option<usize> {
    mpf_second_image(bytes).or_else(|| {
        let xmp = &bytes[..bytes.len().min(65_536)];
        let at = find(xmp, b"Item:Semantic=\"GainMap\"")?;
        let length: usize = attribute(&xmp[at..], "Item:Length")?.parse().ok()?;
        let start = bytes.len().checked_sub(length)?;
        bytes[start..].starts_with(&[0xFF, 0xD8]).then_some(start)
    })
}

/// The offset of the second image an MPF segment (APP2, `MPF\0`) of the primary
/// image lists: its MP entries are 16 bytes (attributes, size, offset from the MPF
/// header, two dependent images).
fn mpf_second_image(bytes: &[u8]) -> Option<usize> {
    let mut at = 2;
    // The primary's marker segments, up to the start of its scan.
    while at + 4 <= bytes.len() && bytes[at] == 0xFF && bytes[at + 1] != 0xDA {
        let length = usize::from(u16::from_be_bytes([bytes[at + 2], bytes[at + 3]]));
        let segment = bytes.get(at + 4..at + 2 + length)?;
        if bytes[at + 1] == 0xE2 && segment.starts_with(b"MPF\0") {
            let header = at + 8;
            let tiff = &segment[4..];
            let big = tiff.starts_with(b"MM");
            let u16_at = |i: usize| {
                let b = tiff.get(i..i + 2)?;
                Some(match big {
                    true => u16::from_be_bytes([b[0], b[1]]),
                    false => u16::from_le_bytes([b[0], b[1]]),
                })
            };
            let u32_at = |i: usize| {
                let b: [u8; 4] = tiff.get(i..i + 4)?.try_into().ok()?;
                Some(match big {
                    true => u32::from_be_bytes(b),
                    false => u32::from_le_bytes(b),
                })
            };
            let ifd = u32_at(4)? as usize;
            let count = usize::from(u16_at(ifd)?);
            for k in 0..count {
                let entry = ifd + 2 + 12 * k;
                if u16_at(entry)? == 0xB002 {
                    let entries = u32_at(entry + 8)? as usize;
                    let offset = u32_at(entries + 16 + 8)? as usize;
                    let start = header.checked_add(offset)?;
                    return bytes
                        .get(start..)
                        .filter(|b| b.starts_with(&[0xFF, 0xD8]))
                        .map(|_| start);
                }
            }
            return None;
        }
        at += 2 + length;
    }
    None
}

/// The gain map's parameters, per channel (a single value for all three, or an
/// `rdf:Seq` of three), with the specification's defaults.
struct Params {
    min: [f32; 3],
    max: [f32; 3],
    gamma: [f32; 3],
    offset_sdr: [f32; 3],
    offset_hdr: [f32; 3],
    base_is_hdr: bool,
}

impl Params {
    fn from_xmp(gain_map: &[u8]) -> Result<Params, String> {
        let head = &gain_map[..gain_map.len().min(65_536)];
        let start = find(head, b"<x:xmpmeta").ok_or("its gain map has no XMP parameters")?;
        let end = find(&head[start..], b"</x:xmpmeta>").map_or(head.len(), |e| start + e);
        let xmp = std::str::from_utf8(&head[start..end])
            .map_err(|_| "its gain map's XMP is not UTF-8")?;
        let value = |name: &str, default: Option<f32>| -> Result<[f32; 3], String> {
            let key = format!("hdrgm:{name}");
            let parse = |text: &str| {
                text.trim()
                    .parse::<f32>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| format!("its gain map's {name} is not a number: '{text}'"))
            };
            if let Some(text) = attribute(xmp.as_bytes(), &key) {
                return Ok([parse(&text)?; 3]);
            }
            if let Some(at) = xmp.find(&format!("<{key}>")) {
                let body = &xmp[at + key.len() + 2..];
                let body = &body[..body.find(&format!("</{key}>")).unwrap_or(body.len())];
                let items: Vec<&str> = body
                    .split("<rdf:li>")
                    .skip(1)
                    .map(|s| s.split("</rdf:li>").next().unwrap_or(""))
                    .collect();
                return match items.as_slice() {
                    [] => Ok([parse(body)?; 3]),
                    [one] => Ok([parse(one)?; 3]),
                    [r, g, b, ..] => Ok([parse(r)?, parse(g)?, parse(b)?]),
                    _ => Err(format!("its gain map's {name} has two values")),
                };
            }
            default
                .map(|d| [d; 3])
                .ok_or_else(|| format!("its gain map has no {name}"))
        };
        let base_is_hdr = attribute(xmp.as_bytes(), "hdrgm:BaseRenditionIsHDR")
            .is_some_and(|v| v.eq_ignore_ascii_case("true"));
        let params = Params {
            min: value("GainMapMin", Some(0.0))?,
            max: value("GainMapMax", None)?,
            gamma: value("Gamma", Some(1.0))?,
            offset_sdr: value("OffsetSDR", Some(1.0 / 64.0))?,
            offset_hdr: value("OffsetHDR", Some(1.0 / 64.0))?,
            base_is_hdr,
        };
        if params.gamma.iter().any(|&g| g <= 0.0) {
            return Err("its gain map's Gamma is not positive".into());
        }
        Ok(params)
    }
}

/// The value of the XML attribute `name="..."` first found in `text`.
fn attribute(text: &[u8], name: &str) -> Option<String> {
    let key = format!("{name}=\"");
    let at = find(text, key.as_bytes())? + key.len();
    let end = text[at..].iter().position(|&b| b == b'"')?;
    String::from_utf8(text[at..at + end].to_vec()).ok()
}

fn find(haystack: &[u8], needle: &[u8]) -> Option<usize> {
    haystack.windows(needle.len()).position(|w| w == needle)
}
