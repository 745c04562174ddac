//! Helpers for the PLY reader's tests: one mesh written in every encoding and
//! scalar type, and short ascii files.

use std::path::Path;

use super::header::Scalar;
use super::parse_ply;
use crate::description::SceneDescription;
use crate::formats::SceneError;

pub(super) const SCALARS: [Scalar; 8] = [
    Scalar::I8,
    Scalar::U8,
    Scalar::I16,
    Scalar::U16,
    Scalar::I32,
    Scalar::U32,
    Scalar::F32,
    Scalar::F64,
];

pub(super) fn parse(bytes: &[u8]) -> Result<SceneDescription, SceneError> {
    parse_ply(bytes, Path::new("t.ply"))
}

pub(super) fn error(text: &str) -> String {
    parse(text.as_bytes()).unwrap_err().to_string()
}

/// Header names, alternating between the original and the sized spelling.
fn name(ty: Scalar, sized: bool) -> &'static str {
    let (original, alias) = match ty {
        Scalar::I8 => ("char", "int8"),
        Scalar::U8 => ("uchar", "uint8"),
        Scalar::I16 => ("short", "int16"),
        Scalar::U16 => ("ushort", "uint16"),
        Scalar::I32 => ("int", "int32"),
        Scalar::U32 => ("uint", "uint32"),
        Scalar::F32 => ("float", "float32"),
        Scalar::F64 => ("double", "float64"),
    };
    if sized { alias } else { original }
}

fn encode(ty: Scalar, value: f64, big_endian: bool) -> Vec<u8> {
    macro_rules! bytes {
        ($t:ty) => {{
            let v = value as $t;
            if big_endian {
                v.to_be_bytes().to_vec()
            } else {
                v.to_le_bytes().to_vec()
            }
        }};
    }
    match ty {
        Scalar::I8 => bytes!(i8),
        Scalar::U8 => bytes!(u8),
        Scalar::I16 => bytes!(i16),
        Scalar::U16 => bytes!(u16),
        Scalar::I32 => bytes!(i32),
        Scalar::U32 => bytes!(u32),
        Scalar::F32 => bytes!(f32),
        Scalar::F64 => bytes!(f64),
    }
}

/// A file's elements as rows of (type, value) properties; lists are a count
/// followed by the items.
pub(super) struct Mesh {
    pub(super) header: String,
    pub(super) rows: Vec<Vec<(Scalar, f64)>>,
}

impl Mesh {
    pub(super) fn ascii(&self) -> Vec<u8> {
        let mut text = format!("ply\nformat ascii 1.0\n{}end_header\n", self.header);
        for row in &self.rows {
            let values: Vec<String> = row.iter().map(|(_, v)| v.to_string()).collect();
            text.push_str(&values.join(" "));
            text.push('\n');
        }
        text.into_bytes()
    }

    pub(super) fn binary(&self, big_endian: bool) -> Vec<u8> {
        let format = if big_endian {
            "binary_big_endian"
        } else {
            "binary_little_endian"
        };
        let mut bytes =
            format!("ply\nformat {format} 1.0\n{}end_header\n", self.header).into_bytes();
        for row in &self.rows {
            for &(ty, v) in row {
                bytes.extend(encode(ty, v, big_endian));
            }
        }
        bytes
    }

    /// The three encodings of this mesh.
    pub(super) fn encodings(&self) -> [(&'static str, Vec<u8>); 3] {
        [
            ("ascii", self.ascii()),
            ("little-endian", self.binary(false)),
            ("big-endian", self.binary(true)),
        ]
    }
}

/// Five vertices, a quad and a triangle; coordinates fit every type.
pub(super) fn quad_and_triangle(
    position: Scalar,
    count: Scalar,
    item: Scalar,
    sized: bool,
) -> Mesh {
    let header = format!(
        "element vertex 5\nproperty {p} x\nproperty {p} y\nproperty {p} z\nelement face 2\nproperty list {c} {i} vertex_indices\n",
        p = name(position, sized),
        c = name(count, sized),
        i = name(item, !sized),
    );
    let points = [
        [0.0, 0.0, 0.0],
        [2.0, 0.0, 0.0],
        [2.0, 2.0, 0.0],
        [0.0, 2.0, 0.0],
        [1.0, 1.0, 3.0],
    ];
    let mut rows: Vec<Vec<(Scalar, f64)>> = points
        .iter()
        .map(|p| p.iter().map(|&v| (position, v)).collect())
        .collect();
    for face in [&[0.0, 1.0, 2.0, 3.0][..], &[0.0, 1.0, 4.0]] {
        let mut row = vec![(count, face.len() as f64)];
        row.extend(face.iter().map(|&i| (item, i)));
        rows.push(row);
    }
    Mesh { header, rows }
}

pub(super) fn triangles(scene: &SceneDescription) -> Vec<[u32; 3]> {
    scene.triangles.iter().map(|t| t.positions).collect()
}

pub(super) const VERTS: &str =
    "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n";
pub(super) const FACES: &str = "element face 1\nproperty list uchar int vertex_indices\n";

pub(super) fn ascii(header: &str, body: &str) -> String {
    format!("ply\nformat ascii 1.0\n{header}end_header\n{body}")
}
