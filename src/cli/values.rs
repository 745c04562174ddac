//! Parsers of option values for the `raytracer` binary (not part of the library).
//! They check the syntax only: a number is a number, a vector is three finite
//! numbers. Ranges are checked once, after the flags are merged over the scene file's
//! values ([`raytracer::options::PartialOptions::resolve`]), so that a flag can
//! replace a bad value of the file; only `-j`, which no scene file sets, is checked
//! here.

use std::ffi::OsString;
use std::num::IntErrorKind;
use std::path::Path;

use raytracer::math::{Float, Vec3};
pub use raytracer::options::Background;
use raytracer::options::defs::Kind;
use raytracer::options::{OPTIONS, OptionDef, OptionId};

/// Most worker threads `-j` accepts: far beyond any core count, low enough that a
/// typo cannot ask the system for millions of threads.
pub const MAX_THREADS: u32 = 1024;

/// A flag whose value is a vector, with an example for messages.
#[derive(Clone, Copy)]
pub struct VectorFlag {
    /// The flag, such as `--look-from`.
    pub name: &'static str,
    /// A good value, such as `0,0.7,1.75`.
    pub example: &'static str,
}

/// The vector flag of `def` (a vector or a background colour), with its example.
pub fn vector_flag(def: &OptionDef) -> VectorFlag {
    VectorFlag {
        name: def.flag,
        example: def.example,
    }
}

/// The flags whose value is a vector.
fn vector_flags() -> impl Iterator<Item = VectorFlag> {
    OPTIONS
        .iter()
        .filter(|d| d.cli && matches!(d.kind, Kind::Vector | Kind::Background))
        .map(vector_flag)
}

/// A whole number: any sign, any size `i64` holds.
pub fn whole_number(s: &str) -> Result<i64, String> {
    s.trim().parse::<i64>().map_err(|e| match e.kind() {
        IntErrorKind::PosOverflow | IntErrorKind::NegOverflow => "too many digits".into(),
        _ => "not a whole number".into(),
    })
}

/// A number; `inf` and `NaN` too, for the range check to refuse by name.
pub fn number(s: &str) -> Result<Float, String> {
    s.trim().parse::<Float>().map_err(|_| "not a number".into())
}

/// A worker thread count in `0..=MAX_THREADS`.
pub fn thread_count(s: &str) -> Result<u32, String> {
    match whole_number(s).map(u32::try_from) {
        Ok(Ok(v)) if v <= MAX_THREADS => Ok(v),
        Ok(_) => Err(format!("not in 0..={MAX_THREADS}")),
        Err(_) => Err(format!("not a whole number (allowed: 0..={MAX_THREADS})")),
    }
}

/// The parser of `flag`'s value: `X,Y,Z`, three finite numbers.
pub fn vector(
    flag: VectorFlag,
) -> impl Fn(&str) -> Result<Vec3, String> + Clone + Send + Sync + 'static {
    move |s| {
        let parts: Vec<&str> = s.split(',').map(str::trim).collect();
        let [x, y, z] = parts[..] else {
            return Err(format!(
                "a vector is written X,Y,Z, three numbers with commas and no spaces, as in {} {}",
                flag.name, flag.example
            ));
        };
        let number = |t: &str| match t.parse::<Float>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(format!("'{t}' is not a finite number in '{s}'")),
        };
        Ok(Vec3::new(number(x)?, number(y)?, number(z)?))
    }
}

/// The parser of `--background`: `transparent` or a colour `R,G,B`.
pub fn background(s: &str) -> Result<Background, String> {
    if s.trim().eq_ignore_ascii_case("transparent") {
        return Ok(Background::Transparent);
    }
    vector(vector_flag(OptionDef::of(OptionId::Background)))(s)
        .map(Background::Colour)
        .map_err(|e| format!("{e} (or 'transparent')"))
}

/// `--aovs`'s value (a type of its own: clap reads a `Vec` field as repeated flags).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AovList(pub Vec<raytracer::Aov>);

/// The parser of `--aovs`: a comma-separated list of output names.
pub fn aov_list(s: &str) -> Result<AovList, String> {
    raytracer::Aov::parse_list(s)
        .map(AovList)
        .map_err(|e| e.to_string())
}

/// What to say when a vector flag's components were given as separate arguments, as
/// in `--look-from 0 0.7 1.75`: clap sees `0` as the value and `0.7` as an unexpected
/// argument (or the scene), which says nothing of the cause. `None` if `args` hold
/// no vector flag whose value is followed by more numbers.
pub fn split_vector(args: &[OsString]) -> Option<String> {
    let args: Vec<&str> = args.iter().map(|a| a.to_str().unwrap_or("")).collect();
    for (i, arg) in args.iter().enumerate() {
        for flag in vector_flags() {
            let (value, rest) = match arg.strip_prefix(flag.name) {
                Some("") if i + 1 < args.len() => (args[i + 1], &args[i + 2..]),
                Some(attached) if attached.starts_with('=') => (&attached[1..], &args[i + 1..]),
                _ => continue,
            };
            if !is_numbers(value) {
                continue;
            }
            let mut pieces = vec![value];
            let mut count = components(value).count();
            for next in rest {
                if count >= 3 || !is_numbers(next) {
                    break;
                }
                pieces.push(next);
                count += components(next).count();
            }
            if pieces.len() == 1 {
                continue;
            }
            let typed = pieces.join(" ");
            let numbers: Vec<&str> = pieces.iter().flat_map(|p| components(p)).collect();
            let name = flag.name;
            let form = "takes a vector as one argument, X,Y,Z with commas and no spaces";
            return Some(if numbers.len() == 3 {
                let joined = numbers.join(",");
                format!("{name} {form}: write {name} {joined}, not {name} {typed}")
            } else {
                let example = flag.example;
                format!("{name} {form}, as in {name} {example} (not {name} {typed})")
            });
        }
    }
    None
}

/// The comma-separated parts of an argument, empty ones left out: `0,` is one.
fn components(arg: &str) -> impl Iterator<Item = &str> {
    arg.split(',').filter(|c| !c.trim().is_empty())
}

/// Whether `arg` is one or more numbers separated by commas.
fn is_numbers(arg: &str) -> bool {
    components(arg).next().is_some() && components(arg).all(|c| c.trim().parse::<f64>().is_ok())
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
    fn numbers_are_parsed_not_range_checked() {
        assert_eq!(whole_number(" 0 "), Ok(0));
        assert_eq!(whole_number("-3"), Ok(-3));
        assert_eq!(whole_number("70000"), Ok(70_000));
        assert_eq!(whole_number("2.5"), Err("not a whole number".into()));
        assert_eq!(
            whole_number("99999999999999999999"),
            Err("too many digits".into())
        );
        assert_eq!(number("180"), Ok(180.0));
        assert!(number("NaN").unwrap().is_nan());
        assert_eq!(number("wide"), Err("not a number".into()));
    }

    #[test]
    fn thread_counts_state_their_range() {
        assert_eq!(thread_count("0"), Ok(0));
        assert_eq!(thread_count("1024"), Ok(1024));
        assert_eq!(thread_count("1025"), Err("not in 0..=1024".into()));
        assert_eq!(thread_count("-1"), Err("not in 0..=1024".into()));
        assert_eq!(
            thread_count("many"),
            Err("not a whole number (allowed: 0..=1024)".into())
        );
    }

    #[test]
    fn vectors_take_negative_components_and_show_how_to_write_them() {
        let parse = vector(vector_flag(OptionDef::of(OptionId::LookFrom)));
        assert_eq!(parse("-0.5,1.5,0.98"), Ok(Vec3::new(-0.5, 1.5, 0.98)));
        assert_eq!(parse(" 1, 2 ,3"), Ok(Vec3::new(1.0, 2.0, 3.0)));
        let form = "a vector is written X,Y,Z, three numbers with commas and no spaces, \
                    as in --look-from 0,0.7,1.75";
        for bad in ["0", "1,2", "0 0.7 1.75", "1,2,3,4"] {
            assert_eq!(parse(bad), Err(form.into()), "{bad}");
        }
        assert_eq!(
            parse("1,2,inf"),
            Err("'inf' is not a finite number in '1,2,inf'".into())
        );
        assert!(parse("1,2,x").is_err());
    }

    #[test]
    fn vectors_split_over_arguments_are_explained() {
        let split = |args: &[&str]| {
            let args: Vec<OsString> = args.iter().map(OsString::from).collect();
            split_vector(&args)
        };
        assert_eq!(
            split(&["r", "render", "s.obj", "--look-from", "0", "0.7", "1.75"]).unwrap(),
            "--look-from takes a vector as one argument, X,Y,Z with commas and no spaces: \
             write --look-from 0,0.7,1.75, not --look-from 0 0.7 1.75"
        );
        assert_eq!(
            split(&["r", "--up=0,", "1,", "0", "s.obj"]).unwrap(),
            "--up takes a vector as one argument, X,Y,Z with commas and no spaces: \
             write --up 0,1,0, not --up 0, 1, 0"
        );
        assert_eq!(
            split(&["r", "--look-to", "-1", "2", "-o", "x.png"]).unwrap(),
            "--look-to takes a vector as one argument, X,Y,Z with commas and no spaces, \
             as in --look-to 0,0.7,0 (not --look-to -1 2)"
        );
        // A complete vector followed by a number, a lone number, or a flag at the end
        // is something else.
        assert_eq!(split(&["r", "--look-from", "0,1,2", "3"]), None);
        assert_eq!(split(&["r", "--look-from", "0", "-o", "x.png"]), None);
        assert_eq!(split(&["r", "s.obj", "--up"]), None);
    }
}
