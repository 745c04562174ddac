//! Binary bodies in either byte order, chosen at compile time. Elements of scalars
//! only, and face elements holding just their index list, are sliced straight out
//! of the bytes (decoded on all threads when there are many); anything else is read
//! value by value.

use rayon::prelude::*;

use super::header::{Element, PropertyType, Role, Scalar};
use super::{Body, MeshReader, integral, unusable_unless};
use crate::description::TriangleDesc;
use crate::formats::error::ParseErrorKind;
use crate::material::MaterialId;
use crate::math::{Float, Vec2, Vec3};
use crate::memory;

/// A binary body; `BIG_ENDIAN` picks the byte order at compile time.
pub(super) struct BinaryBody<'a, const BIG_ENDIAN: bool> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a, const BIG_ENDIAN: bool> BinaryBody<'a, BIG_ENDIAN> {
    pub(super) fn new(bytes: &'a [u8]) -> Self {
        BinaryBody { bytes, pos: 0 }
    }

    /// The next value, as `f64` for float types (exact) and `i64` for integers.
    #[inline(always)]
    fn number(&mut self, ty: Scalar) -> Result<Number, ParseErrorKind> {
        let bytes = self.bytes[self.pos..]
            .get(..ty.size())
            .ok_or(ParseErrorKind::Truncated)?;
        self.pos += ty.size();
        Ok(decode::<BIG_ENDIAN>(bytes, ty))
    }
}

/// A binary value, kept integral when its type is.
#[derive(Clone, Copy)]
enum Number {
    Int(i64),
    Float(f64),
}

impl Number {
    #[inline(always)]
    fn as_float(self) -> f64 {
        match self {
            Number::Int(i) => i as f64,
            Number::Float(f) => f,
        }
    }
}

/// Decodes the value of type `ty` at the start of `bytes`, which holds at least
/// `ty.size()` bytes.
#[inline(always)]
fn decode<const BIG_ENDIAN: bool>(bytes: &[u8], ty: Scalar) -> Number {
    macro_rules! read {
        ($t:ty) => {{
            let raw = *bytes.first_chunk().expect("caller checked the length");
            if BIG_ENDIAN {
                <$t>::from_be_bytes(raw)
            } else {
                <$t>::from_le_bytes(raw)
            }
        }};
    }
    match ty {
        Scalar::I8 => Number::Int(read!(i8) as i64),
        Scalar::U8 => Number::Int(read!(u8) as i64),
        Scalar::I16 => Number::Int(read!(i16) as i64),
        Scalar::U16 => Number::Int(read!(u16) as i64),
        Scalar::I32 => Number::Int(read!(i32) as i64),
        Scalar::U32 => Number::Int(read!(u32) as i64),
        Scalar::F32 => Number::Float(read!(f32) as f64),
        Scalar::F64 => Number::Float(read!(f64)),
    }
}

/// Decodes a value of integer type `ty` (floats are truncated: callers pass integer
/// types only).
#[inline(always)]
fn decode_int<const BIG_ENDIAN: bool>(bytes: &[u8], ty: Scalar) -> i64 {
    match decode::<BIG_ENDIAN>(bytes, ty) {
        Number::Int(i) => i,
        Number::Float(f) => f as i64,
    }
}

/// Item `k` of a list of integer type `item`, with the usual 32-bit index types
/// decoded without a size lookup.
#[inline(always)]
fn list_item<const BIG_ENDIAN: bool>(list: &[u8], k: usize, item: Scalar) -> i64 {
    let four = |k: usize| -> [u8; 4] {
        [
            list[4 * k],
            list[4 * k + 1],
            list[4 * k + 2],
            list[4 * k + 3],
        ]
    };
    match (item, BIG_ENDIAN) {
        (Scalar::I32, false) => i32::from_le_bytes(four(k)) as i64,
        (Scalar::I32, true) => i32::from_be_bytes(four(k)) as i64,
        (Scalar::U32, false) => u32::from_le_bytes(four(k)) as i64,
        (Scalar::U32, true) => u32::from_be_bytes(four(k)) as i64,
        _ => decode_int::<BIG_ENDIAN>(&list[k * item.size()..], item),
    }
}

/// A decoded value as an integer (a float must be integral).
#[inline(always)]
fn integer(value: Number) -> Result<i64, ParseErrorKind> {
    match value {
        Number::Int(i) => Ok(i),
        Number::Float(f) => integral(f).ok_or_else(|| ParseErrorKind::BadNumber(f.to_string())),
    }
}

/// A decoded value as a float, which may be non-finite (see `formats::finite`).
#[inline(always)]
fn any_float(value: Number) -> Float {
    value.as_float() as Float
}

impl<const BIG_ENDIAN: bool> Body for BinaryBody<'_, BIG_ENDIAN> {
    #[inline]
    fn begin(&mut self) -> Result<(), ParseErrorKind> {
        Ok(())
    }

    #[inline]
    fn end(&mut self) -> Result<(), ParseErrorKind> {
        Ok(())
    }

    #[inline]
    fn float(&mut self, ty: Scalar, _name: &str) -> Result<Float, ParseErrorKind> {
        Ok(any_float(self.number(ty)?))
    }

    #[inline]
    fn int(&mut self, ty: Scalar, _name: &str) -> Result<i64, ParseErrorKind> {
        integer(self.number(ty)?)
    }

    #[inline]
    fn skip(&mut self, ty: Scalar, _name: &str) -> Result<(), ParseErrorKind> {
        let end = self.pos + ty.size();
        if end > self.bytes.len() {
            return Err(ParseErrorKind::Truncated);
        }
        self.pos = end;
        Ok(())
    }

    fn line(&self) -> Option<usize> {
        None
    }

    fn remaining(&self) -> usize {
        self.bytes.len() - self.pos
    }

    fn binary_rest(&self) -> Option<(&[u8], bool)> {
        Some((&self.bytes[self.pos..], BIG_ENDIAN))
    }

    fn advance(&mut self, bytes: usize) {
        self.pos += bytes;
    }
}

/// Binary elements with at least this many instances are decoded on all threads.
const PARALLEL_BINARY_ELEMENTS: usize = 1 << 16;

/// Triangles per task of the check that every face decoded in parallel was valid.
const VALID_RUN: usize = 1 << 15;

/// Where a fixed-stride vertex record's values go in the slots of
/// [`MeshReader::read_fixed_stride`]: the position's first, then these.
const NORMAL: usize = 3;
const TEXCOORD: usize = 6;
const COLOUR: usize = 8;

/// One output array of fixed-stride records decoded on all threads into `out`
/// (replacing its contents, in the capacity it has): the values of the `fields`
/// whose slots are `first_slot..first_slot + N`, turned into `T` by `make`.
fn gather<const BIG_ENDIAN: bool, const N: usize, T: Send>(
    records: &[u8],
    stride: usize,
    fields: &[(usize, usize, Scalar)],
    first_slot: usize,
    make: impl Fn([Float; N]) -> T + Sync,
    out: &mut Vec<T>,
) {
    let fields: Vec<(usize, usize, Scalar)> = fields
        .iter()
        .filter(|&&(slot, _, _)| (first_slot..first_slot + N).contains(&slot))
        .map(|&(slot, offset, ty)| (slot - first_slot, offset, ty))
        .collect();
    // Colour channels are scaled by their type; the others are read as they are.
    // The records are all there, so the array is filled from end to end next: on
    // huge pages where they are cheap (the dragon's arrays took 6,000 small-page
    // faults). Not before this point, where a header's counts are only claims.
    reserve_on_huge_pages(out, records.len() / stride);
    let colour = first_slot == COLOUR;
    // The common layout, every value a `float` (positions, normals, texture
    // coordinates): the offsets in a fixed array, read without a type dispatch or a
    // loop over `fields` per record.
    let mut float_offsets = [0; N];
    let all_floats = !colour
        && fields.len() == N
        && fields.iter().all(|&(slot, offset, ty)| {
            float_offsets[slot] = offset;
            ty == Scalar::F32
        });
    if all_floats && float_offsets.iter().all(|&o| o + 4 <= stride) {
        records
            .par_chunks_exact(stride)
            .map(|record| {
                make(float_offsets.map(|offset| {
                    let raw = [0, 1, 2, 3].map(|k| record[offset + k]);
                    match BIG_ENDIAN {
                        true => f32::from_be_bytes(raw),
                        false => f32::from_le_bytes(raw),
                    }
                }))
            })
            .collect_into_vec(out);
        return;
    }
    records
        .par_chunks_exact(stride)
        .map(|record| {
            let mut values = [0.0; N];
            for &(slot, offset, ty) in &fields {
                values[slot] = decode::<BIG_ENDIAN>(&record[offset..], ty).as_float() as Float;
                if colour {
                    values[slot] /= ty.colour_range();
                }
            }
            make(values)
        })
        .collect_into_vec(out);
}

/// Empties `out` and gives it room for `len` elements, on huge pages where they are
/// cheap ([`memory::advise_huge_pages`]), for a parallel `collect_into_vec` of `len`.
fn reserve_on_huge_pages<T>(out: &mut Vec<T>, len: usize) {
    out.clear();
    out.reserve_exact(len);
    memory::advise_huge_pages(out);
}

/// `to` followed by `from`, moving `from` over whole when `to` is empty.
fn append_triangles(to: &mut Vec<TriangleDesc>, mut from: Vec<TriangleDesc>) {
    if to.is_empty() {
        *to = from;
    } else {
        to.append(&mut from);
    }
}

impl MeshReader {
    /// Reads a binary element whose layout allows slicing the bytes directly: only
    /// scalar properties (a fixed stride), or a face element whose one property is
    /// its index list. These cover nearly every PLY file and run several times faster
    /// than [`MeshReader::read_element`]'s value-by-value walk. Returns the bytes read,
    /// or `None` for other layouts.
    pub(super) fn read_binary_fixed<const BIG_ENDIAN: bool>(
        &mut self,
        element: &Element,
        roles: &[Role],
        bytes: &[u8],
    ) -> Option<Result<usize, (usize, ParseErrorKind)>> {
        let scalars: Option<Vec<Scalar>> = element
            .properties
            .iter()
            .map(|p| match p.ty {
                PropertyType::Scalar(ty) => Some(ty),
                PropertyType::List { .. } => None,
            })
            .collect();
        if let Some(types) = scalars {
            return Some(self.read_fixed_stride::<BIG_ENDIAN>(element, roles, &types, bytes));
        }
        match (&element.properties[..], roles) {
            ([property], [Role::Indices]) => match property.ty {
                PropertyType::List { count, item } if count.is_integer() && item.is_integer() => {
                    Some(self.read_index_lists::<BIG_ENDIAN>(element.count, count, item, bytes))
                }
                _ => None,
            },
            _ => None,
        }
    }

    /// Elements of scalars only: one record every `stride` bytes.
    fn read_fixed_stride<const BIG_ENDIAN: bool>(
        &mut self,
        element: &Element,
        roles: &[Role],
        types: &[Scalar],
        bytes: &[u8],
    ) -> Result<usize, (usize, ParseErrorKind)> {
        // (slot in `values`, offset in the record, type) of each value to keep.
        let mut fields = Vec::new();
        let mut offset = 0;
        for (&ty, &role) in types.iter().zip(roles) {
            let slot = match role {
                Role::Position(axis) => Some(axis),
                Role::Normal(axis) => Some(NORMAL + axis),
                Role::TexCoord(axis) => Some(TEXCOORD + axis),
                Role::Colour(axis) => Some(COLOUR + axis),
                Role::Skip | Role::Indices => None,
            };
            if let Some(slot) = slot {
                fields.push((slot, offset, ty));
            }
            offset += ty.size();
        }
        let stride = offset;
        let complete = match stride {
            0 => element.count,
            _ => element.count.min(bytes.len() / stride),
        };
        if !fields.is_empty() && complete == element.count && complete >= PARALLEL_BINARY_ELEMENTS {
            let records = &bytes[..complete * stride];
            // Into the arrays reserved for the header's counts (`with_capacity`).
            let scene = &mut self.scene;
            let mut positions = std::mem::take(&mut scene.positions);
            let mut normals = std::mem::take(&mut scene.normals);
            let mut texcoords = std::mem::take(&mut scene.texcoords);
            let mut colours = std::mem::take(&mut scene.colours);
            gather::<BIG_ENDIAN, 3, _>(records, stride, &fields, 0, Vec3::from, &mut positions);
            if self.has_normals {
                gather::<BIG_ENDIAN, 3, _>(
                    records,
                    stride,
                    &fields,
                    NORMAL,
                    Vec3::from,
                    &mut normals,
                );
            }
            if self.has_texcoords {
                gather::<BIG_ENDIAN, 2, _>(
                    records,
                    stride,
                    &fields,
                    TEXCOORD,
                    Vec2::from,
                    &mut texcoords,
                );
            }
            if self.has_colours {
                // Clamped below 0 once checked (`max` would turn NaN into 0).
                gather::<BIG_ENDIAN, 3, _>(
                    records,
                    stride,
                    &fields,
                    COLOUR,
                    Vec3::from,
                    &mut colours,
                );
            }
            // Serial checks: rayon's short-circuiting `all` pays an atomic per item.
            let finite = normals.iter().all(|n| n.is_finite())
                && texcoords.iter().all(|t| t.is_finite())
                && colours.iter().all(|c| c.is_finite());
            if !finite {
                // Rare: a vertex whose other values are not finite is unusable.
                for (index, position) in positions.iter_mut().enumerate() {
                    let usable = normals.get(index).is_none_or(|n| n.is_finite())
                        && texcoords.get(index).is_none_or(|t| t.is_finite())
                        && colours.get(index).is_none_or(|c| c.is_finite());
                    *position = unusable_unless(usable, *position);
                }
            }
            colours.par_iter_mut().for_each(|c| *c = c.max(Vec3::ZERO));
            self.scene.positions = positions;
            self.scene.normals = normals;
            self.scene.texcoords = texcoords;
            self.scene.colours = colours;
            return Ok(complete * stride);
        }
        if !fields.is_empty() {
            for record in bytes[..complete * stride].chunks_exact(stride) {
                let mut values: [Float; 11] = [0.0; 11];
                for &(slot, offset, ty) in &fields {
                    // A non-finite value is a warning (see `formats::finite`).
                    values[slot] = decode::<BIG_ENDIAN>(&record[offset..], ty).as_float() as Float;
                    if slot >= COLOUR {
                        values[slot] /= ty.colour_range();
                    }
                }
                let usable = values[NORMAL..].iter().all(|v| v.is_finite());
                self.scene
                    .positions
                    .push(unusable_unless(usable, Vec3::from_slice(&values[..NORMAL])));
                if self.has_normals {
                    self.scene
                        .normals
                        .push(Vec3::from_slice(&values[NORMAL..TEXCOORD]));
                }
                if self.has_texcoords {
                    self.scene
                        .texcoords
                        .push(Vec2::from_slice(&values[TEXCOORD..COLOUR]));
                }
                if self.has_colours {
                    let colour = Vec3::from_slice(&values[COLOUR..]);
                    self.scene.colours.push(colour.max(Vec3::ZERO));
                }
            }
        }
        if complete < element.count {
            return Err((complete, ParseErrorKind::Truncated));
        }
        Ok(complete * stride)
    }

    /// Face elements whose one property is the index list, of integer types.
    fn read_index_lists<const BIG_ENDIAN: bool>(
        &mut self,
        faces: usize,
        count: Scalar,
        item: Scalar,
        bytes: &[u8],
    ) -> Result<usize, (usize, ParseErrorKind)> {
        let defined = self.vertex_count;
        let (count_size, item_size) = (count.size(), item.size());
        if faces >= PARALLEL_BINARY_ELEMENTS {
            // Into the array reserved for the header's count while it is empty (one
            // face element, the usual case): no second array of the faces.
            let mut triangles = match self.scene.triangles.is_empty() {
                true => std::mem::take(&mut self.scene.triangles),
                false => Vec::new(),
            };
            let all_valid =
                self.read_triangle_records::<BIG_ENDIAN>(faces, count, item, bytes, &mut triangles);
            if all_valid {
                let read = triangles.len() * (count_size + 3 * item_size);
                append_triangles(&mut self.scene.triangles, triangles);
                return Ok(read);
            }
            if self.scene.triangles.is_empty() {
                // The serial loop below reads them again, into the same capacity.
                triangles.clear();
                self.scene.triangles = triangles;
            }
        }
        let mut pos = 0;
        for face in 0..faces {
            let at = |kind| (face, kind);
            let Some(n) = bytes.get(pos..pos + count_size) else {
                return Err(at(ParseErrorKind::Truncated));
            };
            let n = decode_int::<BIG_ENDIAN>(n, count);
            pos += count_size;
            let list_len = (n.max(0) as usize).saturating_mul(item_size);
            let Some(list) = bytes.get(pos..pos.saturating_add(list_len)) else {
                return Err(at(ParseErrorKind::Truncated));
            };
            pos += list_len;
            // The hot loop decodes indices without `Result`s; anything wrong goes to
            // the general path, which reports it (and would add a face it accepts).
            let index = |k: usize| list_item::<BIG_ENDIAN>(list, k, item);
            let valid = |k: usize| (index(k) as u64) < defined as u64;
            let well_formed = n >= 3
                && self.scene.triangles.len() + (n as usize - 2) <= u32::MAX as usize
                && (0..n as usize).all(valid);
            if !well_formed {
                self.add_face(n, |k| Ok(index(k))).map_err(at)?;
                continue;
            }
            let first = index(0) as u32;
            let mut previous = index(1) as u32;
            let first_triangle = self.scene.triangles.len();
            for k in 2..n as usize {
                let next = index(k) as u32;
                let positions = [first, previous, next];
                self.scene.triangles.push(TriangleDesc {
                    positions,
                    material: MaterialId(0),
                });
                previous = next;
            }
            self.note_polygon(first_triangle, n as usize);
        }
        Ok(pos)
    }

    /// The faces as triangles decoded on all threads into `out` (replacing its
    /// contents), when every face is a valid triangle: then records have one size and
    /// can be cut apart without reading them in order. Returns whether they all were;
    /// if not, the serial loop reads them again, or reports.
    fn read_triangle_records<const BIG_ENDIAN: bool>(
        &self,
        faces: usize,
        count: Scalar,
        item: Scalar,
        bytes: &[u8],
        out: &mut Vec<TriangleDesc>,
    ) -> bool {
        let record = count.size() + 3 * item.size();
        let Some(records) = faces.checked_mul(record).and_then(|len| bytes.get(..len)) else {
            return false;
        };
        // One loop per index type, so the hot loop has no type dispatch.
        let four = |b: &[u8]| [b[0], b[1], b[2], b[3]];
        match (item, BIG_ENDIAN) {
            (Scalar::I32, false) => self.decode_triangles::<BIG_ENDIAN>(
                records,
                count,
                item.size(),
                |b| i32::from_le_bytes(four(b)) as i64,
                out,
            ),
            (Scalar::I32, true) => self.decode_triangles::<BIG_ENDIAN>(
                records,
                count,
                item.size(),
                |b| i32::from_be_bytes(four(b)) as i64,
                out,
            ),
            (Scalar::U32, false) => self.decode_triangles::<BIG_ENDIAN>(
                records,
                count,
                item.size(),
                |b| u32::from_le_bytes(four(b)) as i64,
                out,
            ),
            (Scalar::U32, true) => self.decode_triangles::<BIG_ENDIAN>(
                records,
                count,
                item.size(),
                |b| u32::from_be_bytes(four(b)) as i64,
                out,
            ),
            _ => self.decode_triangles::<BIG_ENDIAN>(
                records,
                count,
                item.size(),
                |b| decode_int::<BIG_ENDIAN>(b, item),
                out,
            ),
        }
        // In runs on all threads: rayon's short-circuiting `all` would pay an atomic
        // per item.
        out.par_chunks(VALID_RUN)
            .map(|run| run.iter().all(|t| !t.positions.contains(&u32::MAX)))
            .reduce(|| true, |a, b| a && b)
    }

    /// Decodes records of a count of type `count` and three indices of `item_size`
    /// bytes read by `index`. A record whose count is not 3 or whose index is out of
    /// range gets index `u32::MAX`, which no valid index equals (there are at most
    /// `u32::MAX` vertices), so one check afterwards finds them.
    fn decode_triangles<const BIG_ENDIAN: bool>(
        &self,
        records: &[u8],
        count: Scalar,
        item_size: usize,
        index: impl Fn(&[u8]) -> i64 + Sync,
        out: &mut Vec<TriangleDesc>,
    ) {
        let count_size = count.size();
        let defined = self.vertex_count as u64;
        // As in `gather`: every record is there.
        reserve_on_huge_pages(out, records.len() / (count_size + 3 * item_size));
        records
            .par_chunks_exact(count_size + 3 * item_size)
            .map(|r| {
                let is_triangle = decode_int::<BIG_ENDIAN>(r, count) == 3;
                let positions = [0, 1, 2].map(|k| {
                    let i = index(&r[count_size + k * item_size..]);
                    if is_triangle && (i as u64) < defined {
                        i as u32
                    } else {
                        u32::MAX
                    }
                });
                TriangleDesc {
                    positions,
                    material: MaterialId(0),
                }
            })
            .collect_into_vec(out);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::formats::ply::testing::{Mesh, parse, quad_and_triangle};

    #[test]
    fn binary_element_errors_name_element_and_index() {
        for big_endian in [false, true] {
            let mesh = quad_and_triangle(Scalar::F32, Scalar::U8, Scalar::I32, false);
            let bytes = mesh.binary(big_endian);
            // Cut inside the last face, then inside the third vertex.
            assert_eq!(
                parse(&bytes[..bytes.len() - 2]).unwrap_err().to_string(),
                "t.ply: face 1: file ends inside the element"
            );
            let header_len = bytes.len() - (5 * 12 + 17 + 13);
            assert_eq!(
                parse(&bytes[..header_len + 30]).unwrap_err().to_string(),
                "t.ply: vertex 2: file ends inside the element"
            );
            // Extra bytes after the last element are only a warning.
            let mut longer = bytes.clone();
            longer.extend([0, 0, 0]);
            assert_eq!(
                parse(&longer).unwrap().warnings,
                ["3 bytes after the last element were ignored"]
            );

            let mut bad = quad_and_triangle(Scalar::F32, Scalar::U8, Scalar::I32, false);
            bad.rows[6][2].1 = 5.0;
            assert_eq!(
                parse(&bad.binary(big_endian)).unwrap_err().to_string(),
                "t.ply: face 1: face index 5 out of range (5 vertices defined)"
            );
            bad.rows[6][0].1 = 2.0;
            bad.rows[6].pop();
            assert_eq!(
                parse(&bad.binary(big_endian)).unwrap_err().to_string(),
                "t.ply: face 1: face has 2 vertices, needs at least 3"
            );
            let mut nan = quad_and_triangle(Scalar::F32, Scalar::U8, Scalar::I32, false);
            nan.rows[3][1].1 = f64::NAN;
            // A warning: the quad at the vertex goes whole, the triangle stays.
            let read = parse(&nan.binary(big_endian)).unwrap();
            assert_eq!(read.triangles.len(), 1);
            assert_eq!(read.triangles[0].positions, [0, 1, 4]);
            assert_eq!(
                read.warnings,
                [
                    "t.ply: 1 vertex with a non-finite coordinate (NaN or infinite); the 2 \
                  triangles using it are dropped"
                ]
            );
            let mut fraction = quad_and_triangle(Scalar::F32, Scalar::U8, Scalar::F32, false);
            fraction.rows[5][1].1 = 0.5;
            assert_eq!(
                parse(&fraction.binary(big_endian)).unwrap_err().to_string(),
                "t.ply: face 0: invalid number '0.5'"
            );
        }
    }

    #[test]
    fn large_binary_files_decode_in_parallel_exactly_like_small_ones() {
        // A triangle strip with normals and texture coordinates, long enough for the
        // parallel paths; the ascii encoding (read in line runs) is the reference.
        let n = PARALLEL_BINARY_ELEMENTS + 100;
        let (f, d, u, i) = (Scalar::F32, Scalar::F64, Scalar::U8, Scalar::U32);
        let mut rows: Vec<Vec<(Scalar, f64)>> = (0..n + 2)
            .map(|k| {
                let (x, y) = ((k / 2) as f64, (k % 2) as f64);
                vec![
                    (f, x),
                    (d, y),
                    (f, 0.5),
                    (f, 0.0),
                    (f, 0.0),
                    (f, 1.0),
                    (u, 7.0),
                    (f, x / 8.0),
                    (f, y),
                ]
            })
            .collect();
        rows.extend((0..n).map(|t| {
            vec![
                (u, 3.0),
                (i, t as f64),
                (i, t as f64 + 1.0),
                (i, t as f64 + 2.0),
            ]
        }));
        let header = format!(
            "element vertex {}\nproperty float x\nproperty double y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty uchar quality\nproperty float u\nproperty float v\nelement face {n}\nproperty list uchar uint vertex_indices\n",
            n + 2
        );
        let mut mesh = Mesh { header, rows };
        let reference = parse(&mesh.ascii()).unwrap();
        assert_eq!(reference.triangles.len(), n);
        assert_eq!(
            reference.texcoords[n + 1],
            Vec2::new((n + 1).div_euclid(2) as f32 / 8.0, 1.0)
        );
        for big_endian in [false, true] {
            let scene = parse(&mesh.binary(big_endian)).unwrap();
            assert_eq!(scene.positions, reference.positions);
            assert_eq!(scene.normals, reference.normals);
            assert_eq!(scene.texcoords, reference.texcoords);
            assert_eq!(scene.triangles, reference.triangles);
        }
        // A position and a normal that are not finite, in the parallel paths: the
        // three triangles of the strip at each vertex are dropped.
        let late = n - 7;
        mesh.rows[late][1].1 = f64::INFINITY;
        mesh.rows[late - 20][3].1 = f64::NAN;
        for big_endian in [false, true] {
            let read = parse(&mesh.binary(big_endian)).unwrap();
            assert_eq!(read.triangles.len(), n - 6);
            assert_eq!(
                read.warnings,
                [
                    "t.ply: 2 vertices with a non-finite coordinate (NaN or infinite); the 6 \
                  triangles using them are dropped"
                ]
            );
        }
        mesh.rows[late][1].1 = 0.0;
        mesh.rows[late - 20][3].1 = 0.0;
        // Bad data late in the file is reported at its own index.
        mesh.rows[n + 2 + late][2].1 = (n + 2) as f64;
        for big_endian in [false, true] {
            let message = parse(&mesh.binary(big_endian)).unwrap_err().to_string();
            assert_eq!(
                message,
                format!(
                    "t.ply: face {late}: face index {} out of range ({} vertices defined)",
                    n + 2,
                    n + 2
                )
            );
        }
        // A quad among the triangles takes the serial path, with the same result.
        mesh.rows[n + 2 + late] = vec![(u, 4.0), (i, 0.0), (i, 1.0), (i, 3.0), (i, 2.0)];
        let scene = parse(&mesh.binary(true)).unwrap();
        assert_eq!(scene.triangles.len(), n + 1);
        assert_eq!(scene.triangles[late].positions, [0, 1, 3]);
        assert_eq!(scene.triangles[late + 1].positions, [0, 3, 2]);
    }
}
