//! NumPy `.npy` files of placements for TOML's `[[instances]]`: an `(N, 4, 4)` array
//! of `float32` or `float64` (little-endian, C order), each `4 x 4` a row-major
//! world-from-object matrix checked by [`affine_from_rows`].
//!
//! Memory is bounded by the file: the header's shape must account for exactly the
//! bytes that follow it before anything is allocated for the matrices.

use std::path::Path;

use glam::Affine3A;

use super::SceneError;
use super::compose::affine_from_rows;
use super::error::ParseErrorKind;

const MAGIC: &[u8] = b"\x93NUMPY";

/// The placements in the `.npy` file `bytes` (named `path` in errors).
///
/// # Errors
/// A file that is not `.npy`, an array whose dtype is not little-endian `f4`/`f8`,
/// in Fortran order, of a shape other than `(N, 4, 4)`, or whose data is not exactly
/// `N * 16` values; a matrix [`affine_from_rows`] refuses (named by its index).
pub fn parse_matrices(bytes: &[u8], path: &Path) -> Result<Vec<Affine3A>, SceneError> {
    let bad = |message: String| SceneError::Parse {
        path: path.to_path_buf(),
        line: 1,
        kind: ParseErrorKind::Instancing(message),
    };
    let Some(rest) = bytes.strip_prefix(MAGIC) else {
        return Err(bad("not a .npy file (no \\x93NUMPY magic)".into()));
    };
    let (header_len, rest) = match rest {
        [1, _, a, b, rest @ ..] => (u16::from_le_bytes([*a, *b]) as usize, rest),
        [2 | 3, _, a, b, c, d, rest @ ..] => (u32::from_le_bytes([*a, *b, *c, *d]) as usize, rest),
        [major, ..] => return Err(bad(format!("unknown .npy version {major}"))),
        [] => return Err(bad("the .npy header is cut short".into())),
    };
    if rest.len() < header_len {
        return Err(bad("the .npy header is cut short".into()));
    }
    let (header, data) = rest.split_at(header_len);
    let header =
        std::str::from_utf8(header).map_err(|_| bad("the .npy header is not text".into()))?;
    let descr =
        value_of(header, "descr").ok_or_else(|| bad("the .npy header has no 'descr'".into()))?;
    let size = match descr.trim_matches(|c| c == '\'' || c == '"') {
        "<f4" => 4,
        "<f8" => 8,
        other => {
            return Err(bad(format!(
                "dtype '{other}': the matrices must be little-endian float32 ('<f4') or float64 ('<f8')"
            )));
        }
    };
    if value_of(header, "fortran_order").is_some_and(|v| v.starts_with("True")) {
        return Err(bad(
            "the array is in Fortran order; save it in C order (np.ascontiguousarray)".into(),
        ));
    }
    let shape =
        value_of(header, "shape").ok_or_else(|| bad("the .npy header has no 'shape'".into()))?;
    let dims: Vec<&str> = shape
        .trim_start_matches('(')
        .split(')')
        .next()
        .unwrap_or("")
        .split(',')
        .map(str::trim)
        .filter(|d| !d.is_empty())
        .collect();
    let count = match dims.as_slice() {
        [n, "4", "4"] => n.parse::<usize>().ok(),
        _ => None,
    }
    .ok_or_else(|| {
        bad(format!(
            "shape ({}): the placements must be an (N, 4, 4) array",
            dims.join(", ")
        ))
    })?;
    let expected = count.checked_mul(16 * size);
    if expected != Some(data.len()) {
        return Err(bad(format!(
            "shape ({count}, 4, 4) of {size}-byte values needs {} bytes of data, the file has {}",
            expected.map_or("too many".to_string(), |e| e.to_string()),
            data.len()
        )));
    }
    let mut matrices = Vec::with_capacity(count);
    for (index, chunk) in data.chunks_exact(16 * size).enumerate() {
        let mut rows = [0.0f64; 16];
        for (value, bytes) in rows.iter_mut().zip(chunk.chunks_exact(size)) {
            *value = match *bytes {
                [a, b, c, d] => f64::from(f32::from_le_bytes([a, b, c, d])),
                _ => f64::from_le_bytes(bytes.try_into().unwrap_or_default()),
            };
        }
        let matrix = affine_from_rows(&rows).map_err(|message| SceneError::Element {
            path: path.to_path_buf(),
            line: None,
            element: "matrix".into(),
            index,
            kind: Box::new(ParseErrorKind::Instancing(message)),
        })?;
        matrices.push(matrix);
    }
    Ok(matrices)
}

/// The text after `'key':` in a header dict, up to the end (the caller reads what
/// it needs from the start).
fn value_of<'a>(header: &'a str, key: &str) -> Option<&'a str> {
    let at = header
        .find(&format!("'{key}'"))
        .or_else(|| header.find(&format!("\"{key}\"")))?;
    let after = &header[at + key.len() + 2..];
    let after = after.trim_start().strip_prefix(':')?.trim_start();
    Some(
        after
            .split_once([',', '}'])
            .map_or(after, |(v, _)| v)
            .trim(),
    )
    .filter(|_| !after.starts_with('('))
    .or(Some(after))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn npy(descr: &str, shape: &str, values: &[f64]) -> Vec<u8> {
        let mut header =
            format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
        while !(MAGIC.len() + 4 + header.len() + 1).is_multiple_of(64) {
            header.push(' ');
        }
        header.push('\n');
        let mut bytes = MAGIC.to_vec();
        bytes.extend([1, 0]);
        bytes.extend((header.len() as u16).to_le_bytes());
        bytes.extend(header.as_bytes());
        for &v in values {
            match descr {
                "<f4" => bytes.extend((v as f32).to_le_bytes()),
                _ => bytes.extend(v.to_le_bytes()),
            }
        }
        bytes
    }

    const TRANSLATE: [f64; 16] = [
        1.0, 0.0, 0.0, 5.0, 0.0, 2.0, 0.0, 6.0, 0.0, 0.0, -1.0, 7.0, 0.0, 0.0, 0.0, 1.0,
    ];

    #[test]
    fn matrices_are_read_row_major_in_both_precisions() {
        for descr in ["<f4", "<f8"] {
            let values: Vec<f64> = TRANSLATE.iter().chain(&TRANSLATE).copied().collect();
            let m = parse_matrices(&npy(descr, "(2, 4, 4)", &values), Path::new("p.npy")).unwrap();
            assert_eq!(m.len(), 2);
            let p = m[1].transform_point3(glam::Vec3::new(1.0, 1.0, 1.0));
            assert_eq!(p, glam::Vec3::new(6.0, 8.0, 6.0));
        }
    }

    #[test]
    fn wrong_files_are_refused_with_what_is_wrong() {
        let path = Path::new("p.npy");
        let error = |bytes: Vec<u8>| parse_matrices(&bytes, path).unwrap_err().to_string();
        assert!(error(npy("<i4", "(1, 4, 4)", &TRANSLATE)).contains("dtype '<i4'"));
        assert!(error(npy("<f8", "(1, 3, 4)", &TRANSLATE[..12])).contains("(N, 4, 4)"));
        // The shape claims a million matrices; the file holds one: refused before
        // anything is allocated for them.
        assert!(error(npy("<f8", "(1000000, 4, 4)", &TRANSLATE)).contains("needs 128000000 bytes"));
        assert!(error(b"hello".to_vec()).contains("not a .npy file"));
        let mut singular = TRANSLATE;
        singular[5] = 0.0;
        let values: Vec<f64> = TRANSLATE.iter().chain(&singular).copied().collect();
        assert_eq!(
            error(npy("<f4", "(2, 4, 4)", &values)),
            "p.npy: matrix 1: singular matrix (determinant 0): it flattens the mesh"
        );
        let mut infinite = TRANSLATE;
        infinite[3] = f64::INFINITY;
        assert!(
            error(npy("<f8", "(1, 4, 4)", &infinite)).contains("matrix 0: non-finite value inf")
        );
    }
}
