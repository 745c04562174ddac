//! Parsers and checks of option values for the `raytracer` binary (not part of the
//! library): each refuses a bad value with the allowed range, and clap names the
//! option.

use std::path::Path;

use raytracer::math::Float;

/// Most worker threads `-j` accepts: far beyond any core count, low enough that a
/// typo cannot ask the system for millions of threads.
pub const MAX_THREADS: u32 = 1024;

/// A whole number in `min..=max`.
pub fn whole_number(
    min: u32,
    max: u32,
) -> impl Fn(&str) -> Result<u32, String> + Clone + Send + Sync + 'static {
    move |s| match s.trim().parse::<i64>() {
        Ok(v) if (i64::from(min)..=i64::from(max)).contains(&v) => Ok(v as u32),
        Ok(_) => Err(format!("not in {min}..={max}")),
        Err(_) => Err(format!("not a whole number (allowed: {min}..={max})")),
    }
}

/// A field of view in degrees, strictly between 0 and 180.
pub fn fov_degrees(s: &str) -> Result<Float, String> {
    const RANGE: &str = "allowed: strictly between 0 and 180 degrees";
    match s.trim().parse::<Float>() {
        Ok(v) if v > 0.0 && v < 180.0 => Ok(v),
        Ok(_) => Err(format!("out of range ({RANGE})")),
        Err(_) => Err(format!("not a number ({RANGE})")),
    }
}

/// Refuses to write the image over the scene file itself.
pub fn check_not_input(scene: &Path, output: &Path) -> anyhow::Result<()> {
    if let (Ok(a), Ok(b)) = (scene.canonicalize(), output.canonicalize()) {
        anyhow::ensure!(
            a != b,
            "cannot write {}: it is the scene file",
            output.display()
        );
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn whole_numbers_state_their_range() {
        let parse = whole_number(1, 64);
        assert_eq!(parse("64"), Ok(64));
        assert_eq!(parse(" 1 "), Ok(1));
        assert_eq!(parse("0"), Err("not in 1..=64".into()));
        assert_eq!(parse("-3"), Err("not in 1..=64".into()));
        assert_eq!(
            parse("99999999999999999999"),
            Err("not a whole number (allowed: 1..=64)".into())
        );
        assert_eq!(
            parse("2.5"),
            Err("not a whole number (allowed: 1..=64)".into())
        );
    }

    #[test]
    fn fov_is_strictly_between_0_and_180() {
        assert_eq!(fov_degrees("60"), Ok(60.0));
        for bad in ["0", "180", "-1", "inf", "NaN"] {
            assert!(
                fov_degrees(bad)
                    .unwrap_err()
                    .contains("strictly between 0 and 180"),
                "{bad}"
            );
        }
        assert!(fov_degrees("wide").unwrap_err().starts_with("not a number"));
    }
}
