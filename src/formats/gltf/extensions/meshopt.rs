//! `EXT_meshopt_compression` and its ratified successor `KHR_meshopt_compression`: a
//! buffer view's bytes are a meshoptimizer stream in another buffer (vertex codec for
//! `ATTRIBUTES`, index codec for `TRIANGLES` and `INDICES`), optionally followed by a
//! filter (`OCTAHEDRAL`, `QUATERNION`, `EXPONENTIAL`; and `COLOR`, KHR only). The
//! KHR extension has the same objects and adds version 1 of the vertex codec and the
//! `COLOR` filter, both of which meshoptimizer 1.3 (the crate's) decodes. Each such view is decoded once, before any accessor reads it, into
//! `count * byteStride` bytes of its own buffer; the view's uncompressed "fallback"
//! buffer (often without a `uri`, marked `"fallback": true`) is never read.
//!
//! The decoders are meshoptimizer's own (the `meshopt` crate, which builds its C++),
//! which are written for untrusted input: a malformed stream is an error code, never
//! a read or write outside the slices given. Their preconditions (strides, counts,
//! the filter's stride) are checked here first, since the C++ asserts them.

use gltf::json::Value;

/// The extension's name, as in `extensionsUsed`.
pub(in super::super) const NAME: &str = "EXT_meshopt_compression";

/// The ratified extension's name.
pub(in super::super) const KHR_NAME: &str = "KHR_meshopt_compression";

/// Which of the two extensions a buffer view uses: what its streams and filters may be.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(in super::super) enum Variant {
    /// `EXT_meshopt_compression`: vertex codec version 0, no `COLOR` filter.
    Ext,
    /// `KHR_meshopt_compression`: vertex codec version 0 or 1, the `COLOR` filter.
    Khr,
}

impl Variant {
    /// The extension's name.
    pub(in super::super) fn name(self) -> &'static str {
        match self {
            Variant::Ext => NAME,
            Variant::Khr => KHR_NAME,
        }
    }
}

/// How a view's data was encoded (the extension's `mode`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Mode {
    /// Vertex codec: `count` elements of `byteStride` bytes.
    Attributes,
    /// Index codec for triangle lists: `count` indices, a multiple of three.
    Triangles,
    /// Index sequence codec: `count` indices of any topology.
    Indices,
}

/// The filter applied to decoded attributes (the extension's `filter`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Filter {
    None,
    /// Unit vectors in octahedral encoding: 4 or 8 bytes per element.
    Octahedral,
    /// Unit quaternions as three components and the index of the fourth: 8 bytes.
    Quaternion,
    /// Floats as an 8-bit exponent and a 24-bit mantissa per component.
    Exponential,
    /// RGBA colours in YCoCg with alpha (KHR only): 4 or 8 bytes per element.
    Color,
}

/// A buffer view's `EXT_meshopt_compression` object.
#[derive(Clone, Debug)]
pub(in super::super) struct Compressed {
    /// The buffer holding the compressed stream.
    pub(in super::super) buffer: usize,
    byte_offset: usize,
    byte_length: usize,
    /// The size of each element, which the buffer view's `byteStride` (if it has
    /// one) must be.
    pub(in super::super) byte_stride: usize,
    count: usize,
    mode: Mode,
    filter: Filter,
    variant: Variant,
}

/// How many bytes a stream of `compressed` bytes can decode to at most: version 0
/// of the vertex codec (EXT's) spends at least two header bits on each group of 16
/// bytes of a byte lane (at most 64 bytes out per byte in); version 1 (KHR's) can
/// mark a byte lane of a whole block of up to 256 elements (of at most 8192 bytes)
/// zero with two bits of its control header, at most 1024 bytes out per byte in; the
/// index codec spends at least a byte per triangle (12 bytes out) or per index (4
/// bytes out); plus the stream's fixed tail. A view claiming more is refused before
/// anything is allocated, so memory is bounded by the file's size.
fn most_decoded(compressed: usize, variant: Variant) -> usize {
    let ratio = match variant {
        Variant::Ext => 64,
        Variant::Khr => 1024,
    };
    compressed.saturating_mul(ratio).saturating_add(256)
}

impl Compressed {
    /// Reads and checks the extension object of a buffer view.
    ///
    /// # Errors
    /// A missing or mistyped member, an unknown mode or filter, or a stride, count or
    /// filter the mode does not allow.
    pub(in super::super) fn parse(extension: &Value, variant: Variant) -> Result<Self, String> {
        let number = |key: &str, default: Option<usize>| -> Result<usize, String> {
            match extension.get(key) {
                None => default.ok_or_else(|| format!("no '{key}'")),
                Some(v) => v
                    .as_u64()
                    .and_then(|v| usize::try_from(v).ok())
                    .ok_or_else(|| format!("'{key}' is {v}, not a count of bytes or elements")),
            }
        };
        let text = |key: &str, default: &'static str| -> Result<String, String> {
            match extension.get(key) {
                None => Ok(default.to_owned()),
                Some(Value::String(s)) => Ok(s.clone()),
                Some(v) => Err(format!("'{key}' is {v}, not a string")),
            }
        };
        let mode = match text("mode", "")?.as_str() {
            "ATTRIBUTES" => Mode::Attributes,
            "TRIANGLES" => Mode::Triangles,
            "INDICES" => Mode::Indices,
            "" => return Err("no 'mode'".into()),
            other => {
                return Err(format!(
                    "mode '{other}' is none of ATTRIBUTES, TRIANGLES and INDICES"
                ));
            }
        };
        let filter = match (text("filter", "NONE")?.as_str(), variant) {
            ("NONE", _) => Filter::None,
            ("OCTAHEDRAL", _) => Filter::Octahedral,
            ("QUATERNION", _) => Filter::Quaternion,
            ("EXPONENTIAL", _) => Filter::Exponential,
            ("COLOR", Variant::Khr) => Filter::Color,
            ("COLOR", Variant::Ext) => {
                return Err(format!(
                    "filter COLOR is {KHR_NAME}'s, not {NAME}'s: name the extension {KHR_NAME}"
                ));
            }
            (other, _) => {
                return Err(format!(
                    "filter '{other}' is none of NONE, OCTAHEDRAL, QUATERNION, EXPONENTIAL and COLOR"
                ));
            }
        };
        let compressed = Compressed {
            buffer: number("buffer", None)?,
            byte_offset: number("byteOffset", Some(0))?,
            byte_length: number("byteLength", None)?,
            byte_stride: number("byteStride", None)?,
            count: number("count", None)?,
            mode,
            filter,
            variant,
        };
        compressed.check()?;
        Ok(compressed)
    }

    /// The extension's rules for strides, counts and filters (which the decoders
    /// assert), and the bound on the decoded size.
    fn check(&self) -> Result<(), String> {
        let stride = self.byte_stride;
        match self.mode {
            Mode::Attributes if stride == 0 || stride > 256 || !stride.is_multiple_of(4) => {
                return Err(format!(
                    "ATTRIBUTES with a byteStride of {stride}, not a multiple of 4 from 4 to 256"
                ));
            }
            Mode::Triangles | Mode::Indices if stride != 2 && stride != 4 => {
                return Err(format!(
                    "{:?} with a byteStride of {stride}, not 2 or 4",
                    self.mode
                ));
            }
            Mode::Triangles if !self.count.is_multiple_of(3) => {
                return Err(format!(
                    "TRIANGLES with a count of {}, not a multiple of 3",
                    self.count
                ));
            }
            _ => {}
        }
        let filter_fits = match self.filter {
            Filter::None => true,
            _ if self.mode != Mode::Attributes => false,
            Filter::Octahedral => stride == 4 || stride == 8,
            Filter::Quaternion => stride == 8,
            Filter::Exponential => true,
            Filter::Color => stride == 4 || stride == 8,
        };
        if !filter_fits {
            return Err(format!(
                "filter {:?} with mode {:?} and a byteStride of {stride}",
                self.filter, self.mode
            ));
        }
        let size = self.decoded_size()?;
        if size > most_decoded(self.byte_length, self.variant) {
            return Err(format!(
                "{} elements of {stride} bytes ({size} bytes) cannot come from {} compressed bytes",
                self.count, self.byte_length
            ));
        }
        Ok(())
    }

    /// Which extension the view uses.
    pub(in super::super) fn variant(&self) -> Variant {
        self.variant
    }

    /// `count * byteStride`: the size of the decoded view.
    pub(in super::super) fn decoded_size(&self) -> Result<usize, String> {
        (self.count)
            .checked_mul(self.byte_stride)
            .ok_or_else(|| format!("{} elements of {} bytes", self.count, self.byte_stride))
    }

    /// The compressed stream within `buffer` (the data of buffer [`Self::buffer`]).
    ///
    /// # Errors
    /// The stream lies outside the buffer.
    pub(in super::super) fn stream<'b>(&self, buffer: &'b [u8]) -> Result<&'b [u8], String> {
        self.byte_offset
            .checked_add(self.byte_length)
            .and_then(|end| buffer.get(self.byte_offset..end))
            .ok_or_else(|| {
                format!(
                    "its {} bytes from byte {} lie outside buffer {} of {} bytes",
                    self.byte_length,
                    self.byte_offset,
                    self.buffer,
                    buffer.len()
                )
            })
    }

    /// Decodes `stream` (from [`Self::stream`]) into `count * byteStride` bytes, the
    /// filter applied.
    ///
    /// # Errors
    /// The stream is malformed (cut short, another codec version, bad data).
    pub(in super::super) fn decode(&self, stream: &[u8]) -> Result<Vec<u8>, String> {
        let size = self.decoded_size()?;
        let header = stream.first().copied().unwrap_or(0);
        let expected = match self.mode {
            Mode::Attributes => 0xa0,
            Mode::Triangles => 0xe0,
            Mode::Indices => 0xd0,
        };
        // Index codec version 1 is what every encoder since 2020 writes, and both
        // extensions allow it (KHR asks for it; version 0 is read all the same).
        // Vertex codec version 1 is KHR's alone (and the decoded-size bound of EXT
        // assumes version 0).
        let newest = match (self.mode, self.variant) {
            (Mode::Attributes, Variant::Ext) => 0,
            _ => 1,
        };
        if header & 0xf0 != expected || header & 0x0f > newest {
            let hint = match (self.mode, self.variant, header) {
                (Mode::Attributes, Variant::Ext, 0xa1) => {
                    format!(" (vertex codec version 1 is {KHR_NAME}'s)")
                }
                _ => String::new(),
            };
            return Err(format!(
                "the stream begins with byte 0x{header:02x}, not a {:?} stream of a version {} allows{hint}",
                self.mode,
                self.variant.name()
            ));
        }
        // Words, so that the filters' 16- and 32-bit accesses are aligned; asked for
        // fallibly, as the size, though bounded by the stream's, may not fit.
        let mut words: Vec<u32> = Vec::new();
        words
            .try_reserve_exact(size.div_ceil(4))
            .map_err(|_| format!("{size} decoded bytes do not fit in memory"))?;
        words.resize(size.div_ceil(4), 0);
        let out = words.as_mut_ptr().cast::<std::ffi::c_void>();
        let (count, stride) = (self.count, self.byte_stride);
        // SAFETY: `out` holds at least `count * stride` bytes; the strides and
        // counts were checked against what each decoder asserts (`check`); the
        // decoders read only `stream.len()` bytes of `stream`.
        let code = unsafe {
            match self.mode {
                Mode::Attributes => meshopt::ffi::meshopt_decodeVertexBuffer(
                    out,
                    count,
                    stride,
                    stream.as_ptr(),
                    stream.len(),
                ),
                Mode::Triangles => meshopt::ffi::meshopt_decodeIndexBuffer(
                    out,
                    count,
                    stride,
                    stream.as_ptr(),
                    stream.len(),
                ),
                Mode::Indices => meshopt::ffi::meshopt_decodeIndexSequence(
                    out,
                    count,
                    stride,
                    stream.as_ptr(),
                    stream.len(),
                ),
            }
        };
        if code != 0 {
            return Err(format!(
                "the {:?} stream is malformed or cut short (decoder error {code})",
                self.mode
            ));
        }
        // SAFETY: as above; each filter's stride was checked in `check`, and the
        // words are aligned for its 16- and 32-bit components.
        unsafe {
            match self.filter {
                Filter::None => {}
                Filter::Octahedral => meshopt::ffi::meshopt_decodeFilterOct(out, count, stride),
                Filter::Quaternion => meshopt::ffi::meshopt_decodeFilterQuat(out, count, stride),
                Filter::Exponential => meshopt::ffi::meshopt_decodeFilterExp(out, count, stride),
                Filter::Color => meshopt::ffi::meshopt_decodeFilterColor(out, count, stride),
            }
        }
        let mut bytes: Vec<u8> = bytemuck::cast_slice(&words).to_vec();
        bytes.truncate(size);
        Ok(bytes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn object(json: &str) -> Value {
        gltf::json::deserialize::from_str(json).unwrap()
    }

    #[test]
    fn strides_counts_and_filters_the_decoders_assert_are_refused() {
        for (rest, message) in [
            (
                r#""byteStride": 6, "mode": "ATTRIBUTES""#,
                "not a multiple of 4",
            ),
            (
                r#""byteStride": 260, "mode": "ATTRIBUTES""#,
                "not a multiple of 4",
            ),
            (r#""byteStride": 8, "mode": "INDICES""#, "not 2 or 4"),
            (
                r#""byteStride": 4, "mode": "TRIANGLES""#,
                "not a multiple of 3",
            ),
            (
                r#""byteStride": 4, "mode": "ATTRIBUTES", "filter": "QUATERNION""#,
                "filter Quaternion",
            ),
            (
                r#""byteStride": 4, "mode": "INDICES", "filter": "EXPONENTIAL""#,
                "filter Exponential",
            ),
            (r#""byteStride": 4, "mode": "LINES""#, "mode 'LINES'"),
            (
                r#""byteStride": 4, "mode": "ATTRIBUTES", "filter": "X""#,
                "filter 'X'",
            ),
            (r#""byteStride": 4"#, "no 'mode'"),
            (
                r#""byteStride": -4, "mode": "ATTRIBUTES""#,
                "'byteStride' is -4",
            ),
        ] {
            let value = object(&format!(
                r#"{{"buffer": 0, "byteLength": 100, "count": 4, {rest}}}"#
            ));
            let error = Compressed::parse(&value, Variant::Ext).unwrap_err();
            assert!(error.contains(message), "{rest}: {error}");
        }
        let fine = r#"{"buffer": 0, "byteLength": 100, "count": 4, "byteStride": 8,
            "mode": "ATTRIBUTES", "filter": "OCTAHEDRAL"}"#;
        assert!(Compressed::parse(&object(fine), Variant::Ext).is_ok());
    }

    #[test]
    fn a_view_claiming_more_than_its_stream_can_hold_is_refused_before_allocating() {
        let value = object(
            r#"{"buffer": 0, "byteLength": 16, "byteStride": 256, "count": 1000000000000,
                "mode": "ATTRIBUTES"}"#,
        );
        let error = Compressed::parse(&value, Variant::Ext).unwrap_err();
        assert!(
            error.contains("cannot come from 16 compressed bytes"),
            "{error}"
        );
    }

    /// A view of `stream` as `count` elements of `stride`, of the EXT extension.
    fn view(stream: &[u8], count: usize, stride: usize, mode: Mode, filter: Filter) -> Compressed {
        Compressed {
            buffer: 0,
            byte_offset: 0,
            byte_length: stream.len(),
            byte_stride: stride,
            count,
            mode,
            filter,
            variant: Variant::Ext,
        }
    }

    /// `stream` through [`Compressed::decode`] as `count` elements of `stride`.
    fn decoded(stream: &[u8], count: usize, stride: usize, mode: Mode, filter: Filter) -> Vec<u8> {
        let compressed = view(stream, count, stride, mode, filter);
        compressed.check().unwrap();
        compressed.decode(stream).unwrap()
    }

    #[test]
    fn khr_streams_of_vertex_codec_version_1_with_the_colour_filter_decode_to_the_colours() {
        let colours: Vec<[f32; 4]> = (0..50)
            .map(|i| {
                let t = i as f32 / 49.0;
                [t, 1.0 - t, (t * 7.0).fract(), 0.5 + 0.5 * t]
            })
            .collect();
        let filtered: Vec<[u8; 4]> = meshopt::encode_filter_color(&colours, 8);
        let stream = meshopt::encode_vertex_buffer_level(&filtered, 2, Some(1)).unwrap();
        assert_eq!(stream[0], 0xa1, "vertex codec version 1");
        let khr = Compressed {
            variant: Variant::Khr,
            ..view(&stream, colours.len(), 4, Mode::Attributes, Filter::Color)
        };
        khr.check().unwrap();
        let bytes = khr.decode(&stream).unwrap();
        // The colours as 8-bit unsigned normalized values, within the filter's
        // rounding (YCoCg in 8 bits, alpha in 7).
        for (colour, got) in colours.iter().zip(bytes.chunks(4)) {
            for (c, &g) in colour.iter().zip(got) {
                assert!(
                    (f32::from(g) - c * 255.0).abs() <= 3.0,
                    "{colour:?} as {got:?}"
                );
            }
        }
        // Both are KHR's alone: under EXT, errors that say so.
        let ext = view(&stream, colours.len(), 4, Mode::Attributes, Filter::None);
        let error = ext.decode(&stream).unwrap_err();
        assert!(
            error.contains("version 1 is KHR_meshopt_compression's"),
            "{error}"
        );
        let colour = object(
            r#"{"buffer": 0, "byteLength": 100, "count": 4, "byteStride": 4,
                "mode": "ATTRIBUTES", "filter": "COLOR"}"#,
        );
        let error = Compressed::parse(&colour, Variant::Ext).unwrap_err();
        assert!(
            error.contains("filter COLOR is KHR_meshopt_compression's"),
            "{error}"
        );
        assert!(Compressed::parse(&colour, Variant::Khr).is_ok());
        // The colour filter takes 4 or 8 bytes.
        let wide = object(
            r#"{"buffer": 0, "byteLength": 100, "count": 4, "byteStride": 12,
                "mode": "ATTRIBUTES", "filter": "COLOR"}"#,
        );
        let error = Compressed::parse(&wide, Variant::Khr).unwrap_err();
        assert!(error.contains("filter Color"), "{error}");
    }

    // gltfpack (the glTF fixtures of tests/gltf_compression.rs) writes neither index
    // sequences nor quaternions: meshoptimizer's own encoders make them here.
    #[test]
    fn index_sequences_decode_to_the_indices_encoded() {
        let indices: Vec<u32> = vec![0, 1, 2, 3, 4, 5, 2, 7, 100, 3, 3, 99];
        let stream = meshopt::encode_index_sequence(&indices, 101).unwrap();
        let bytes = decoded(&stream, indices.len(), 4, Mode::Indices, Filter::None);
        let got: Vec<u32> = bytemuck::pod_collect_to_vec(&bytes);
        assert_eq!(got, indices);
        let bytes = decoded(&stream, indices.len(), 2, Mode::Indices, Filter::None);
        let got: Vec<u16> = bytemuck::pod_collect_to_vec(&bytes);
        assert!(got.iter().map(|&i| u32::from(i)).eq(indices));
    }

    #[test]
    fn quaternion_filtered_attributes_decode_to_the_unit_quaternions_encoded() {
        let quaternions: Vec<[f32; 4]> = (0..40)
            .map(|i| {
                let i = i as f32;
                let q =
                    glam::Quat::from_euler(glam::EulerRot::XYZ, i * 0.3, i * 0.7 - 2.0, i * 0.11);
                q.to_array()
            })
            .collect();
        let filtered = meshopt::encode_filter_quat(&quaternions, 12);
        // Version 0 of the vertex codec, as the extension requires.
        let stream = meshopt::encode_vertex_buffer_level(&filtered, 2, Some(0)).unwrap();
        let bytes = decoded(
            &stream,
            quaternions.len(),
            8,
            Mode::Attributes,
            Filter::Quaternion,
        );
        let got: Vec<[i16; 4]> = bytemuck::pod_collect_to_vec(&bytes);
        for (q, g) in quaternions.iter().zip(&got) {
            let g = glam::Vec4::from(g.map(|c| f32::from(c) / 32767.0));
            let q = glam::Vec4::from(*q);
            // q and -q are the same rotation.
            let error = (g - q).length().min((g + q).length());
            assert!(error < 2e-3, "{q} decoded as {g}");
        }
        // A stream of the vertex codec's version 1 is not this extension's.
        let newer = meshopt::encode_vertex_buffer_level(&filtered, 2, Some(1)).unwrap();
        let compressed = view(
            &newer,
            quaternions.len(),
            8,
            Mode::Attributes,
            Filter::Quaternion,
        );
        let error = compressed.decode(&newer).unwrap_err();
        assert!(error.contains("begins with byte 0xa1"), "{error}");
    }
}
