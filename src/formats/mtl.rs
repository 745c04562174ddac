//! The MTL reader: `newmtl`, `Ka`, `Kd`, `Ks`, `Ke`, `Ns`, `Ni`, `d`, `Tr`, `al`.

use std::path::Path;

use super::error::{ParseErrorKind, SceneError};
use super::lex;
use crate::material::Material;
use crate::math::{Float, Vec3};

/// Parses an MTL file's text; `path` names it in errors. Materials keep file order.
///
/// # Errors
/// A malformed supported line, with its line number.
pub fn parse_mtl(text: &[u8], path: &Path) -> Result<Vec<Material>, SceneError> {
    parse_mtl_with_warnings(text, path).map(|(materials, _)| materials)
}

/// [`parse_mtl`], with the warnings about values that other tools write and this
/// renderer reads as the nearest valid one, each naming file and line.
pub(crate) fn parse_mtl_with_warnings(
    text: &[u8],
    path: &Path,
) -> Result<(Vec<Material>, Vec<String>), SceneError> {
    let at = |line, kind| SceneError::Parse {
        path: path.to_path_buf(),
        line,
        kind,
    };
    lex::check_text(text).map_err(|(line, kind)| at(line, kind))?;
    let mut materials: Vec<Material> = Vec::new();
    // The first line with a negative `Ns`, and how many there are.
    let mut negative_ns: Option<(usize, usize)> = None;
    for (line_number, line) in lex::lines(text) {
        let clamped = parse_line(line, &mut materials).map_err(|kind| at(line_number, kind))?;
        if clamped {
            let (_, count) = negative_ns.get_or_insert((line_number, 0));
            *count += 1;
        }
    }
    let warnings = negative_ns
        .map(|(line, count)| {
            format!(
                "{}:{line}: 'Ns' below 0 read as 0 ({count} line{})",
                path.display(),
                if count == 1 { "" } else { "s" }
            )
        })
        .into_iter()
        .collect();
    Ok((materials, warnings))
}

/// Reads one line into `materials`; `true` if it was an `Ns` below 0, read as 0.
fn parse_line(line: &[u8], materials: &mut Vec<Material>) -> Result<bool, ParseErrorKind> {
    let mut tokens = lex::tokens(line);
    let Some(keyword) = tokens.next() else {
        return Ok(false);
    };
    if keyword == b"newmtl" {
        // Blender writes `newmtl` with no name for a material it has none for (and
        // `usemtl` with none to use it): the empty name is a name.
        let name = lex::rest_of_line(line, b"newmtl");
        materials.push(Material::named(String::from_utf8_lossy(name)));
        return Ok(false);
    }
    let known = matches!(
        keyword,
        b"Ka" | b"Kd" | b"Ks" | b"Ke" | b"Ns" | b"Ni" | b"d" | b"Tr" | b"al"
    );
    if !known {
        return Ok(false);
    }
    // `Ka spectral file.rfl` and `Ka xyz x y z` are other colour spaces we do not model.
    let mut peek = tokens.clone();
    if matches!(peek.next(), Some(b"spectral" | b"xyz")) {
        return Ok(false);
    }
    let material = materials
        .last_mut()
        .ok_or_else(|| ParseErrorKind::PropertyBeforeNewmtl(lex::show(keyword)))?;
    match keyword {
        b"Ka" => material.ambient = colour("Ka", &mut tokens)?,
        b"Kd" => material.diffuse = colour("Kd", &mut tokens)?,
        b"Ks" => material.specular = colour("Ks", &mut tokens)?,
        b"Ke" => material.emission = colour("Ke", &mut tokens)?,
        b"Ns" => {
            // Some exporters write a negative exponent; other readers clamp it to 0
            // (a negative one would make highlights infinite where they should fade).
            let ns = lex::floats::<1>("Ns", &mut tokens)?[0];
            material.shininess = ns.max(0.0);
            return Ok(ns < 0.0);
        }
        b"Ni" => material.ior = lex::floats::<1>("Ni", &mut tokens)?[0],
        b"d" => material.opacity = lex::floats::<1>("d", &mut tokens)?[0],
        b"Tr" => material.opacity = 1.0 - lex::floats::<1>("Tr", &mut tokens)?[0],
        b"al" => material.albedo = colour("al", &mut tokens)?.into(),
        _ => unreachable!("filtered by `known` above"),
    }
    Ok(false)
}

/// An RGB triple; a single value means grey.
fn colour<'a>(
    statement: &'static str,
    tokens: &mut (impl Iterator<Item = &'a [u8]> + Clone),
) -> Result<Vec3, ParseErrorKind> {
    if tokens.clone().take(3).count() == 1 {
        let grey: Float = lex::floats::<1>(statement, tokens)?[0];
        return Ok(Vec3::splat(grey));
    }
    lex::vec3(statement, tokens)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Vec<Material>, SceneError> {
        parse_mtl(text.as_bytes(), Path::new("test.mtl"))
    }

    #[test]
    fn reads_every_field_and_defaults() {
        let m = parse(
            "newmtl a\n Ka 0.1 0.2 0.3\n\tKd 0.5\nKs 1 1 1\nKe 0 0 2\nNs 64\nNi 1.5\nd 0.25\nal 0.1 0.2 0.7\nnewmtl b b\nTr 0.75\nillum 2\n",
        )
        .unwrap();
        assert_eq!(m.len(), 2);
        assert_eq!(m[0].ambient, Vec3::new(0.1, 0.2, 0.3));
        assert_eq!(m[0].diffuse, Vec3::splat(0.5));
        assert_eq!(m[0].specular, Vec3::ONE);
        assert_eq!(m[0].emission, Vec3::new(0.0, 0.0, 2.0));
        assert_eq!((m[0].shininess, m[0].ior, m[0].opacity), (64.0, 1.5, 0.25));
        assert_eq!(m[0].albedo, [0.1, 0.2, 0.7]);
        assert_eq!(m[1].name, "b b");
        assert_eq!(m[1].opacity, 0.25);
        assert_eq!(m[1].albedo, [1.0, 0.0, 0.0]);
    }

    #[test]
    fn errors_name_file_and_line() {
        let err = parse("newmtl a\nKd 0.5 x 0.5\n").unwrap_err();
        assert_eq!(err.to_string(), "test.mtl:2: invalid number 'x'");
        let err = parse("Kd 1 1 1\n").unwrap_err();
        assert_eq!(err.to_string(), "test.mtl:1: 'Kd' before any 'newmtl'");
        let err = parse("newmtl a\nKs 1 1\n").unwrap_err();
        assert_eq!(err.to_string(), "test.mtl:2: 'Ks' needs 3 values, found 2");
        let err = parse("newmtl a\nNs\n").unwrap_err();
        assert_eq!(err.to_string(), "test.mtl:2: 'Ns' needs 1 value, found 0");
    }

    #[test]
    fn a_negative_ns_is_read_as_zero_with_one_warning() {
        let text = "newmtl a\nNs -5\nnewmtl b\nNs 10\nnewmtl c\nNs -0.5\n";
        let (m, warnings) = parse_mtl_with_warnings(text.as_bytes(), Path::new("t.mtl")).unwrap();
        assert_eq!(
            m.iter().map(|m| m.shininess).collect::<Vec<_>>(),
            [0.0, 10.0, 0.0]
        );
        assert_eq!(warnings, ["t.mtl:2: 'Ns' below 0 read as 0 (2 lines)"]);
        let (_, warnings) =
            parse_mtl_with_warnings(b"newmtl a\nNs 0\n", Path::new("t.mtl")).unwrap();
        assert!(warnings.is_empty());
    }
}
