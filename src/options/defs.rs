//! Every render option, declared once: its name on the command line, in a TOML scene
//! file and as a Python keyword, the kind of value it takes, its range, its default
//! and its help, as ripgrep declares its flags (`crates/core/flags/defs.rs`: one
//! definition per flag, from which the parser, the help and the man page follow).
//!
//! The front ends derive what they need from [`OPTIONS`]: the command line's clap
//! arguments and their help (`src/cli/args.rs`), the keys of a TOML file's `[camera]`
//! and `[render]` tables ([`crate::formats::toml`]), the Python bindings' keyword
//! arguments and their messages (`python/src/lib.rs`), and the range checks of
//! [`super::PartialOptions::resolve`], whose errors name the flag, the file, line and
//! key, or the keyword. `tests/options_table.rs` holds the Python stub's keyword list
//! and `docs/options.md` to the table.
//!
//! Adding an option: a field of [`super::RenderOptions`] and [`super::PartialOptions`]
//! (and its line in [`super::PartialOptions::or`]), an [`OptionId`] and one entry here.

use std::fmt;

use super::{Background, Origin, PartialOptions, Projection, Sourced};
use crate::math::{Float, Vec3};

/// Names each option, so that code can refer to an entry of [`OPTIONS`] without
/// spelling one of its names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[allow(missing_docs)]
pub enum OptionId {
    Width,
    Height,
    Fov,
    LookFrom,
    LookTo,
    Up,
    CameraToWorld,
    Intrinsics,
    Depth,
    Mode,
    Spp,
    Exposure,
    ToneMap,
    ApertureRadius,
    FocusDistance,
    Seed,
    DefaultLight,
    Env,
    EnvStrength,
    EnvRotation,
    Background,
}

/// The kind of value an option takes: how each front end reads it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Kind {
    /// A whole number, kept as wide as anyone writes it (`i64`), so that `-4` is
    /// reported as -4.
    Whole,
    /// A number; infinity and NaN are read, for the range check to refuse by name.
    Number,
    /// Three finite numbers: `X,Y,Z` on the command line, an array in TOML, any
    /// sequence in Python.
    Vector,
    /// One of a list of names, each with its help.
    Choice(&'static [(&'static str, &'static str)]),
    /// On or off: a TOML and Python boolean; on the command line a switch that turns
    /// the option off (`--no-...`).
    SwitchOff,
    /// An image file or a colour `R,G,B` (the environment).
    FileOrColour,
    /// A colour `R,G,B`, or `transparent` on the command line (the background).
    Background,
    /// A camera-to-world matrix, four rows of four numbers (no flag).
    Matrix,
    /// OpenCV's pinhole intrinsics `fx, fy, cx, cy` in pixels (no flag).
    Intrinsics,
}

/// The values an option allows, beyond its [`Kind`]; [`Range::check`] gives the one
/// message every front end shows after its name of the option.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Range {
    /// Any value of the kind.
    Any,
    /// Whole numbers `min..=max`.
    Whole(i64, i64),
    /// Numbers strictly between the two.
    Open(Float, Float),
    /// Numbers from `-bound` to `bound`, in a unit.
    Within(Float, &'static str),
    /// Finite numbers of at least 0, called the noun, with a note.
    NotNegative(&'static str, &'static str),
    /// Finite numbers greater than 0, called the noun.
    Positive(&'static str),
    /// Finite numbers.
    Finite,
}

impl Range {
    /// Whether `value` is allowed; else what is wrong, as in `65 is not in 1..=64`.
    ///
    /// # Errors
    /// The message, starting with the value as given.
    pub fn check(self, value: f64) -> Result<(), String> {
        let shown = value as Float;
        let ok = match self {
            Range::Any => true,
            Range::Whole(min, max) => (min as f64..=max as f64).contains(&value),
            Range::Open(low, high) => value > f64::from(low) && value < f64::from(high),
            Range::Within(bound, _) => value.abs() <= f64::from(bound),
            Range::NotNegative(..) => value.is_finite() && value >= 0.0,
            Range::Positive(_) => value.is_finite() && value > 0.0,
            Range::Finite => value.is_finite(),
        };
        if ok {
            return Ok(());
        }
        Err(match self {
            Range::Any => unreachable!("every value is allowed"),
            Range::Whole(min, max) => format!("{value} is not in {min}..={max}"),
            Range::Open(low, high) => format!("{shown} is not strictly between {low} and {high}"),
            Range::Within(bound, unit) => {
                format!("{shown} is not between -{bound} and {bound}{unit}")
            }
            Range::NotNegative(noun, note) => {
                format!("{shown} is not a finite {noun} of 0 or more{note}")
            }
            Range::Positive(noun) => format!("{shown} is not a finite {noun} greater than 0"),
            Range::Finite => format!("{shown} is not a finite number"),
        })
    }

    /// [`Range::check`] of a whole number (exact for any `i64`).
    ///
    /// # Errors
    /// As [`Range::check`].
    pub fn check_whole(self, value: i64) -> Result<(), String> {
        match self {
            Range::Whole(min, max) if !(min..=max).contains(&value) => {
                Err(format!("{value} is not in {min}..={max}"))
            }
            Range::Whole(..) => Ok(()),
            _ => self.check(value as f64),
        }
    }

    /// The range in the documentation's words: `1..=65536`.
    pub fn describe(self) -> String {
        match self {
            Range::Any => String::new(),
            Range::Whole(min, max) => format!("{min}..={max}"),
            Range::Open(low, high) => format!("strictly between {low} and {high}"),
            Range::Within(bound, unit) => format!("-{bound}..={bound}{unit}"),
            Range::NotNegative(..) => "0 or more".into(),
            Range::Positive(_) => "greater than 0".into(),
            Range::Finite => "finite".into(),
        }
    }
}

/// One value as a front end read it, before its range check.
#[derive(Clone, Debug, PartialEq)]
pub enum Value {
    /// Of [`Kind::Whole`].
    Whole(i64),
    /// Of [`Kind::Number`].
    Number(Float),
    /// Of [`Kind::Vector`].
    Vector(Vec3),
    /// Of [`Kind::Choice`]: the name as given.
    Name(String),
    /// Of [`Kind::SwitchOff`]: whether the option is on.
    Switch(bool),
    /// Of [`Kind::FileOrColour`]: the file, or the colour as `R,G,B`.
    Text(String),
    /// Of [`Kind::Background`].
    Background(Background),
    /// Of [`Kind::Matrix`]: rows of four.
    Matrix([[f64; 4]; 4]),
    /// Of [`Kind::Intrinsics`]: `fx, fy, cx, cy`.
    Four([Float; 4]),
}

/// How [`OptionDef::set`] stores a value into [`PartialOptions`]: a value of the
/// wrong kind, or a name not among the choices, is a message.
type Setter = fn(&mut PartialOptions, Value, Origin) -> Result<(), String>;

/// One render option, as every front end names and reads it.
pub struct OptionDef {
    /// Which option.
    pub id: OptionId,
    /// The flag that sets it, as errors name it: `--width`. Options without a flag
    /// ([`OptionDef::cli`] false) still have one, for messages.
    pub flag: &'static str,
    /// Whether the command line has the flag.
    pub cli: bool,
    /// The key of a TOML scene file, `section.key`: `camera.width`.
    pub toml: Option<&'static str>,
    /// Another key of the same table that sets the option another way: the
    /// environment's `environment.color` beside its `environment.file`, both of
    /// which `--env` replaces.
    pub toml_also: Option<&'static str>,
    /// The Python keyword argument: `width`.
    pub python: &'static str,
    /// Whether the option belongs to the scene rather than to one render (what the
    /// scene emits: the environment): Python's `Scene.render` refuses it.
    pub scene: bool,
    /// The kind of value.
    pub kind: Kind,
    /// The values allowed.
    pub range: Range,
    /// The value's name in help: `PIXELS`.
    pub value_name: &'static str,
    /// The default, in the documentation's words.
    pub default: &'static str,
    /// A valid value as the command line spells it, for the documentation and tests.
    pub example: &'static str,
    /// The first paragraph of the help, ending with a full stop (the short help is
    /// without it).
    pub help: &'static str,
    /// The further paragraphs of the long help, if any.
    pub details: &'static str,
    /// Stores a value.
    pub set: Setter,
}

impl fmt::Debug for OptionDef {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.flag)
    }
}

impl OptionDef {
    /// The definition of `id`.
    pub fn of(id: OptionId) -> &'static OptionDef {
        OPTIONS
            .iter()
            .find(|d| d.id == id)
            .expect("every option has a definition")
    }

    /// The definition whose Python keyword is `keyword`.
    pub fn by_keyword(keyword: &str) -> Option<&'static OptionDef> {
        OPTIONS.iter().find(|d| d.python == keyword)
    }

    /// The definition whose flag is `flag` (`--width`).
    pub fn by_flag(flag: &str) -> Option<&'static OptionDef> {
        OPTIONS.iter().find(|d| d.flag == flag)
    }

    /// The definitions of a TOML table, `camera` or `render`, in order.
    pub fn in_section(section: &str) -> impl Iterator<Item = (&'static OptionDef, &'static str)> {
        OPTIONS.iter().filter_map(move |d| {
            let (s, key) = d.toml?.split_once('.')?;
            (s == section).then_some((d, key))
        })
    }

    /// Stores `value`, given at `origin`, into `options`.
    ///
    /// # Errors
    /// A value of another kind, or a name not among the choices.
    pub fn store(
        &self,
        options: &mut PartialOptions,
        value: Value,
        origin: Origin,
    ) -> Result<(), String> {
        (self.set)(options, value, origin)
    }

    /// The TOML keys that set the option, `section.key`: [`OptionDef::toml`], then
    /// [`OptionDef::toml_also`].
    pub fn toml_keys(&self) -> impl Iterator<Item = &'static str> {
        self.toml.into_iter().chain(self.toml_also)
    }

    /// The choices' names of a [`Kind::Choice`] option.
    pub fn choices(&self) -> Vec<&'static str> {
        match self.kind {
            Kind::Choice(choices) => choices.iter().map(|(name, _)| *name).collect(),
            _ => Vec::new(),
        }
    }
}

/// `name` if it is one of `choices`, spelt exactly (scene files' and Python's rule;
/// the command line's parser lists the choices itself).
///
/// # Errors
/// serde's message for an unknown name, as TOML's other names have it.
pub fn choice(choices: &[(&str, &str)], name: String) -> Result<Value, String> {
    if choices.iter().any(|(n, _)| *n == name) {
        return Ok(Value::Name(name));
    }
    let names: Vec<String> = choices.iter().map(|(n, _)| format!("`{n}`")).collect();
    Err(format!(
        "unknown variant `{name}`, expected one of {}",
        names.join(", ")
    ))
}

fn sourced<T>(value: T, origin: Origin) -> Option<Sourced<T>> {
    Some(Sourced::new(value, origin))
}

fn kind_error(value: &Value) -> String {
    format!("{value:?} is not a value of this option")
}

/// A setter of a whole-number field.
macro_rules! whole {
    ($field:ident) => {
        |o: &mut PartialOptions, v: Value, origin: Origin| match v {
            Value::Whole(v) => {
                o.$field = sourced(v, origin);
                Ok(())
            }
            v => Err(kind_error(&v)),
        }
    };
}

/// A setter of a number field.
macro_rules! number {
    ($field:ident) => {
        |o: &mut PartialOptions, v: Value, origin: Origin| match v {
            Value::Number(v) => {
                o.$field = sourced(v, origin);
                Ok(())
            }
            v => Err(kind_error(&v)),
        }
    };
}

/// A setter of a vector field.
macro_rules! vector {
    ($field:ident) => {
        |o: &mut PartialOptions, v: Value, origin: Origin| match v {
            Value::Vector(v) => {
                o.$field = sourced(v, origin);
                Ok(())
            }
            v => Err(kind_error(&v)),
        }
    };
}

/// A setter of a field of one of `names`, parsed by its `FromStr`.
macro_rules! named {
    ($field:ident) => {
        |o: &mut PartialOptions, v: Value, origin: Origin| match v {
            Value::Name(name) => {
                o.$field = sourced(name.parse()?, origin);
                Ok(())
            }
            v => Err(kind_error(&v)),
        }
    };
}

/// The modes with their help.
const MODES: &[(&str, &str)] = &[
    (
        "full",
        "Whitted-style: Phong lighting, hard shadows, reflection and refraction, tone mapped",
    ),
    (
        "depth",
        "Distance to the nearest hit, normalized by the farthest (misses white)",
    ),
    (
        "normal",
        "Surface normal facing the camera as colour, n/2 + 1/2 (misses black)",
    ),
    (
        "path",
        "Physically based path tracing: area lights from Ke, global illumination",
    ),
];

/// The tone maps with their help.
const TONE_MAPS: &[(&str, &str)] = &[
    ("standard", "Exposure, clamp at 1, sRGB curve"),
    (
        "khronos-neutral",
        "Khronos PBR Neutral: true base colours, highlights compressed towards white",
    ),
    (
        "agx",
        "AgX (Blender, three.js): filmic, desaturates bright colours",
    ),
    ("aces", "ACES filmic (Stephen Hill's fit, as three.js)"),
];

/// Every render option, in the order the command line's help lists them.
pub static OPTIONS: [OptionDef; 21] = [
    OptionDef {
        id: OptionId::Width,
        flag: "--width",
        cli: true,
        toml: Some("camera.width"),
        toml_also: None,
        python: "width",
        scene: false,
        kind: Kind::Whole,
        range: Range::Whole(1, super::MAX_DIMENSION as i64),
        value_name: "PIXELS",
        default: "640",
        example: "320",
        help: "Image width in pixels (1..=65536) [default: 640].",
        details: "Given without --height, the height keeps the aspect ratio of the scene file's image size (640x480 if it sets none), rounded to the nearest pixel: --width 320 renders 320x240.",
        set: whole!(width),
    },
    OptionDef {
        id: OptionId::Height,
        flag: "--height",
        cli: true,
        toml: Some("camera.height"),
        toml_also: None,
        python: "height",
        scene: false,
        kind: Kind::Whole,
        range: Range::Whole(1, super::MAX_DIMENSION as i64),
        value_name: "PIXELS",
        default: "480",
        example: "240",
        help: "Image height in pixels (1..=65536; at most 16384x16384 pixels in all) [default: 480].",
        details: "Given without --width, the width keeps the aspect ratio of the scene file's image size (640x480 if it sets none), rounded to the nearest pixel: --height 240 renders 320x240.",
        set: whole!(height),
    },
    OptionDef {
        id: OptionId::Fov,
        flag: "--fov",
        cli: true,
        toml: Some("camera.fov"),
        toml_also: None,
        python: "fov",
        scene: false,
        kind: Kind::Number,
        range: Range::Open(0.0, 180.0),
        value_name: "DEGREES",
        default: "90; 40 when the camera frames the scene",
        example: "60",
        help: "Vertical field of view in degrees, strictly between 0 and 180 [default: 90; 40 when the camera frames the scene].",
        details: "The horizontal one follows from width / height: pixels are square. The scene file's field of view, if it sets one, wins over both. The narrower field of view of a camera that frames the scene (see --look-from) is a model viewer's: the model is seen with little distortion.",
        set: number!(fov_degrees),
    },
    OptionDef {
        id: OptionId::LookFrom,
        flag: "--look-from",
        cli: true,
        toml: Some("camera.look_from"),
        toml_also: None,
        python: "look_from",
        scene: false,
        kind: Kind::Vector,
        range: Range::Any,
        value_name: "X,Y,Z",
        default: "framed",
        example: "0,0.7,1.75",
        help: "Camera position, three numbers with commas and no spaces [default: framed].",
        details: "When neither --look-from nor --look-to is given (here or in a scene file), the camera frames the scene as a model viewer does: from the front (+z, where glTF models face; -y when --up is 0,0,1) and above, 22 degrees up and 30 degrees to the right, from as close as lets the corners of the scene's bounds fit 92% of the image's limiting dimension, centred; a scene flat in x, y or z (one polygon, a floor) is seen face-on, along -x, -y or -z. Given alone, it looks at the centre of the bounds. An empty scene, or --look-to alone, keeps 0,0,0.",
        set: vector!(look_from),
    },
    OptionDef {
        id: OptionId::LookTo,
        flag: "--look-to",
        cli: true,
        toml: Some("camera.look_to"),
        toml_also: None,
        python: "look_to",
        scene: false,
        kind: Kind::Vector,
        range: Range::Any,
        value_name: "X,Y,Z",
        default: "framed",
        example: "0,0.7,0",
        help: "Point the camera looks at [default: framed].",
        details: "When the camera frames the scene (see --look-from), the point level with the centre of the scene's bounds that centres their projection; the centre itself when only --look-from is given; 0,0,-1 when the scene is empty. It must differ from the camera position.",
        set: vector!(look_to),
    },
    OptionDef {
        id: OptionId::Up,
        flag: "--up",
        cli: true,
        toml: Some("camera.up"),
        toml_also: None,
        python: "up",
        scene: false,
        kind: Kind::Vector,
        range: Range::Any,
        value_name: "X,Y,Z",
        default: "0,1,0",
        example: "0,1,0",
        help: "World up direction of the camera [default: 0,1,0].",
        details: "Any length but zero.",
        set: vector!(up),
    },
    OptionDef {
        id: OptionId::CameraToWorld,
        flag: "--camera-to-world",
        cli: false,
        toml: Some("camera.matrix"),
        toml_also: None,
        python: "camera_to_world",
        scene: false,
        kind: Kind::Matrix,
        range: Range::Any,
        value_name: "MATRIX",
        default: "none",
        example: "1,0,0,0,0,1,0,0,0,0,1,5,0,0,0,1",
        help: "A camera-to-world matrix, four rows of four numbers (OpenGL's convention: the camera looks down its -Z axis, +Y up), instead of --look-from, --look-to and --up.",
        details: "Its upper-left 3x3 must be a rotation (columns of length 1 and perpendicular within 1e-4, no mirror image) and its last row 0, 0, 0, 1; it renders as the look-at camera of the same pose, in every mode, and a lens's focus defaults to 1 unit ahead. A scene file gives it as camera.matrix, not beside look_from, look_to and up.",
        set: |o, v, origin| match v {
            Value::Matrix(m) => {
                let pose = super::pose_from_matrix(m)?;
                o.look_from = sourced(pose.look_from, origin.clone());
                o.look_to = sourced(pose.look_to, origin.clone());
                o.up = sourced(pose.up, origin);
                Ok(())
            }
            v => Err(kind_error(&v)),
        },
    },
    OptionDef {
        id: OptionId::Intrinsics,
        flag: "--intrinsics",
        cli: false,
        toml: Some("camera.intrinsics"),
        toml_also: None,
        python: "intrinsics",
        scene: false,
        kind: Kind::Intrinsics,
        range: Range::Any,
        value_name: "FX,FY,CX,CY",
        default: "none",
        example: "500,500,320,240",
        help: "OpenCV's pinhole intrinsics fx, fy, cx, cy in pixels, instead of --fov.",
        details: "Pixel (u, v), the top-left pixel's centre being (0, 0), sees the camera-space direction ((u - cx)/fx, (v - cy)/fy, 1) in OpenCV's axes (x right, y down, z ahead); the focal lengths must be greater than 0.",
        set: |o, v, origin| match v {
            Value::Four([fx, fy, cx, cy]) => {
                o.projection = sourced(Projection::Intrinsics { fx, fy, cx, cy }, origin);
                Ok(())
            }
            v => Err(kind_error(&v)),
        },
    },
    OptionDef {
        id: OptionId::Depth,
        flag: "--depth",
        cli: true,
        toml: Some("render.depth"),
        toml_also: None,
        python: "depth",
        scene: false,
        kind: Kind::Whole,
        range: Range::Whole(1, super::MAX_RECURSION_DEPTH as i64),
        value_name: "N",
        default: "4; 64 in path mode",
        example: "3",
        help: "Recursion depth of full mode (1..=64): 1 traces primary and shadow rays only [default: 4; 64 in path mode].",
        details: "With glass, each level can double the rays per pixel. In path mode, the most path segments (1..=1024; Mitsuba's max_depth). Depth and normal modes ignore it.",
        set: whole!(depth),
    },
    OptionDef {
        id: OptionId::Mode,
        flag: "--mode",
        cli: true,
        toml: Some("render.mode"),
        toml_also: None,
        python: "mode",
        scene: false,
        kind: Kind::Choice(MODES),
        range: Range::Any,
        value_name: "MODE",
        default: "full",
        example: "depth",
        help: "What to render [default: full].",
        details: "",
        set: named!(mode),
    },
    OptionDef {
        id: OptionId::Spp,
        flag: "--spp",
        cli: true,
        toml: Some("render.spp"),
        toml_also: None,
        python: "spp",
        scene: false,
        kind: Kind::Whole,
        range: Range::Whole(1, crate::sampler::MAX_SAMPLES_PER_PIXEL as i64),
        value_name: "N",
        default: "1; 4 in full mode under the default light rig; 64 in path mode",
        example: "4",
        help: "Samples per pixel in full and path modes (1..=65536): 1 traces pixel centres, more take stratified jittered positions with a fixed seed (same image every run) [default: 1; 4 in full mode under the default light rig; 64 in path mode].",
        details: "Under the default light rig (a scene without lights of its own) full mode takes 4 unless --aovs asks for extra outputs, which keep one ray through each pixel centre, as do scenes with lights.",
        set: whole!(samples_per_pixel),
    },
    OptionDef {
        id: OptionId::Exposure,
        flag: "--exposure",
        cli: true,
        toml: Some("render.exposure"),
        toml_also: None,
        python: "exposure",
        scene: false,
        kind: Kind::Number,
        range: Range::Within(super::MAX_EXPOSURE_STOPS, " stops"),
        value_name: "STOPS",
        default: "0",
        example: "1.5",
        help: "Path mode's exposure in stops: PNG values are the radiance times 2^STOPS, then the sRGB curve (-64..=64) [default: 0].",
        details: "",
        set: number!(exposure),
    },
    OptionDef {
        id: OptionId::ToneMap,
        flag: "--tonemap",
        cli: true,
        toml: Some("render.tonemap"),
        toml_also: None,
        python: "tonemap",
        scene: false,
        kind: Kind::Choice(TONE_MAPS),
        range: Range::Any,
        value_name: "OPERATOR",
        default: "khronos-neutral",
        example: "agx",
        help: "Path mode's tone map of PNG output, after the exposure [default: khronos-neutral].",
        details: "Full mode keeps SPEC's tone map and ignores this; EXR output stays linear.",
        set: named!(tonemap),
    },
    OptionDef {
        id: OptionId::ApertureRadius,
        flag: "--aperture-radius",
        cli: true,
        toml: Some("camera.aperture_radius"),
        toml_also: None,
        python: "aperture_radius",
        scene: false,
        kind: Kind::Number,
        range: Range::NotNegative("radius", " (0 is a pinhole)"),
        value_name: "R",
        default: "0",
        example: "0.05",
        help: "Radius of the camera's thin lens in scene units, 0 or more [default: 0].",
        details: "Points nearer or farther than --focus-distance blur into discs; 0 is a pinhole, everything sharp. Full and path modes only (depth and normal modes and orthographic cameras keep a pinhole); take more --spp to smooth the blur.",
        set: number!(aperture_radius),
    },
    OptionDef {
        id: OptionId::FocusDistance,
        flag: "--focus-distance",
        cli: true,
        toml: Some("camera.focus_distance"),
        toml_also: None,
        python: "focus_distance",
        scene: false,
        kind: Kind::Number,
        range: Range::Positive("distance"),
        value_name: "D",
        default: "the distance from --look-from to --look-to",
        example: "2.5",
        help: "Distance in scene units from the lens to the plane in focus, along the view direction, greater than 0 [default: the distance from --look-from to --look-to].",
        details: "Used with --aperture-radius.",
        set: number!(focus_distance),
    },
    OptionDef {
        id: OptionId::Seed,
        flag: "--seed",
        cli: true,
        toml: Some("render.seed"),
        toml_also: None,
        python: "seed",
        scene: false,
        kind: Kind::Whole,
        range: Range::Whole(0, u32::MAX as i64),
        value_name: "N",
        default: "0",
        example: "7",
        help: "Seed of the random numbers (0..=4294967295): another seed, another equally valid image; the same seed, the same image on any number of threads [default: 0].",
        details: "",
        set: whole!(seed),
    },
    OptionDef {
        id: OptionId::DefaultLight,
        flag: "--no-default-light",
        cli: true,
        toml: Some("render.default_light"),
        toml_also: None,
        python: "default_light",
        scene: false,
        kind: Kind::SwitchOff,
        range: Range::Any,
        value_name: "",
        default: "on",
        example: "false",
        help: "Render a scene with no light ('P', a scene file's [[light]]) and no emitter ('Ke') as it is: black but for its ambient colour in full mode, black in path mode. By default such a scene gets a light rig at the camera (full mode) or a studio environment before a grey backdrop (path mode), with a warning.",
        details: "",
        set: |o, v, origin| match v {
            Value::Switch(on) => {
                o.default_light = sourced(on, origin);
                Ok(())
            }
            v => Err(kind_error(&v)),
        },
    },
    OptionDef {
        id: OptionId::Env,
        flag: "--env",
        cli: true,
        toml: Some("environment.file"),
        toml_also: Some("environment.color"),
        python: "env",
        scene: true,
        kind: Kind::FileOrColour,
        range: Range::Any,
        value_name: "FILE|R,G,B",
        default: "the scene's; none",
        example: "0.5,0.5,0.5",
        help: "Path mode's environment, lighting the scene from infinitely far away and seen where camera rays leave it: an equirectangular image (Radiance .hdr, OpenEXR, PNG or JPEG; +Y up, oriented as three.js and Blender show it) or a colour R,G,B. Replaces the scene file's [environment] [default: the scene's; none].",
        details: "OpenEXR of every compression, lossy DWAA and DWAB included (as HDRI packages ship them); PNG and JPEG are read as sRGB, a JPEG with an HDR gain map (Ultra HDR, as viser ships Poly Haven's HDRIs) at its full range. A scene file gives either environment.file, relative to its folder, or environment.color, a number or [r, g, b], not both.",
        set: |o, v, origin| match v {
            Value::Text(text) => {
                o.env = sourced(text, origin);
                Ok(())
            }
            v => Err(kind_error(&v)),
        },
    },
    OptionDef {
        id: OptionId::EnvStrength,
        flag: "--env-strength",
        cli: true,
        toml: Some("environment.strength"),
        toml_also: None,
        python: "env_strength",
        scene: true,
        kind: Kind::Number,
        range: Range::NotNegative("strength", ""),
        value_name: "X",
        default: "the scene's; 1",
        example: "2",
        help: "Multiplies the environment's radiance (0..) [default: the scene's; 1].",
        details: "",
        set: number!(env_strength),
    },
    OptionDef {
        id: OptionId::EnvRotation,
        flag: "--env-rotation",
        cli: true,
        toml: Some("environment.rotation"),
        toml_also: None,
        python: "env_rotation",
        scene: true,
        kind: Kind::Number,
        range: Range::Finite,
        value_name: "DEGREES",
        default: "the scene's; 0",
        example: "90",
        help: "Turns the environment about +Y by DEGREES, right-handed: at 90, what was seen along +X is seen along -Z [default: the scene's; 0].",
        details: "",
        set: number!(env_rotation),
    },
    OptionDef {
        id: OptionId::Background,
        flag: "--background",
        cli: true,
        toml: Some("environment.background"),
        toml_also: None,
        python: "background",
        scene: true,
        kind: Kind::Background,
        range: Range::Any,
        value_name: "R,G,B|transparent",
        default: "the environment",
        example: "0.5,0.5,0.5",
        help: "What camera rays that leave the scene see, instead of the environment (which still lights the scene): a colour R,G,B (path mode), or `transparent` (both modes): an RGBA PNG, or an EXR with `A`, whose alpha is the fraction of each pixel's camera rays that hit the scene [default: the environment].",
        details: "",
        set: |o, v, origin| match v {
            Value::Background(b) => {
                o.background = sourced(b, origin);
                Ok(())
            }
            Value::Vector(c) => {
                o.background = sourced(Background::Colour(c), origin);
                Ok(())
            }
            v => Err(kind_error(&v)),
        },
    },
];

/// The Python stub's declaration of every keyword option, as
/// `python/raytracer/_raytracer.pyi` must hold it (`tests/options_table.rs`): a
/// `TypedDict` the render functions take as `**options: Unpack[...]`.
pub fn python_stub(class: &str, scene: bool) -> String {
    let mut out = format!("class {class}(TypedDict, total=False):\n");
    for def in OPTIONS.iter().filter(|d| d.scene == scene) {
        let kind = match def.kind {
            Kind::Whole => "Optional[int]".to_string(),
            Kind::Number => "Optional[float]".into(),
            Kind::Vector | Kind::Background => "Optional[Vector]".into(),
            Kind::Choice(choices) => format!(
                "Optional[Literal[{}]]",
                choices
                    .iter()
                    .map(|(name, _)| format!("\"{name}\""))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
            Kind::SwitchOff => "Optional[bool]".into(),
            Kind::FileOrColour => "Union[StrPath, Vector, None]".into(),
            Kind::Matrix => "Optional[npt.ArrayLike]".into(),
            Kind::Intrinsics => "Optional[Tuple[float, float, float, float]]".into(),
        };
        out.push_str(&format!("    {}: {kind}\n", def.python));
    }
    out
}

/// The flag with its value as the tables show it (`` `--width PIXELS` ``), or `none`.
fn flag_cell(def: &OptionDef) -> String {
    match (def.cli, def.kind) {
        (false, _) => "none".to_string(),
        (true, Kind::SwitchOff) => format!("`{}`", def.flag),
        (true, _) => format!("`{} {}`", def.flag, def.value_name.replace('|', "\\|")),
    }
}

/// The first paragraph of the help without its default and full stop.
fn summary(def: &OptionDef) -> &'static str {
    def.help
        .split(" [default:")
        .next()
        .unwrap_or(def.help)
        .trim_end_matches('.')
}

/// The whole help as one table cell: the summary, each choice with its help, and
/// the details.
fn explanation(def: &OptionDef) -> String {
    let mut text = summary(def).to_string();
    if let Kind::Choice(choices) = def.kind {
        let each: Vec<String> = choices.iter().map(|(n, h)| format!("`{n}`: {h}")).collect();
        text = format!("{text}: {}", each.join("; "));
    }
    if !def.details.is_empty() {
        text = format!("{text}. {}", def.details.trim_end_matches('.'));
    }
    text.replace('|', "\\|")
}

/// The command line's table of the render options (`docs/cli.md`): flag, default
/// and the whole help, as `raytracer render --help` gives it.
pub fn cli_table() -> String {
    let mut out = String::from("| flag | default | meaning |\n|---|---|---|\n");
    for def in OPTIONS.iter().filter(|d| d.cli) {
        out.push_str(&format!(
            "| {} | {} | {} |\n",
            flag_cell(def),
            def.default,
            explanation(def)
        ));
    }
    out
}

/// A TOML table's keys (`camera`, `render`, `environment`) as `docs/scene-format.md`
/// lists them: key, the whole help, default, and the flag or Python keyword.
pub fn toml_table(section: &str) -> String {
    let mut out = String::from("| key | meaning | default | flag |\n|---|---|---|---|\n");
    for def in &OPTIONS {
        let keys: Vec<String> = def
            .toml_keys()
            .filter_map(|k| k.strip_prefix(section)?.strip_prefix('.'))
            .map(|k| format!("`{k}`"))
            .collect();
        if keys.is_empty() {
            continue;
        }
        let flag = match def.cli {
            true => format!("`{}`", def.flag),
            false => format!("Python's `{}=`", def.python),
        };
        out.push_str(&format!(
            "| {} | {} | {} | {flag} |\n",
            keys.join(" or "),
            explanation(def),
            def.default
        ));
    }
    out
}

/// The documentation's table of every option (`docs/options.md`).
pub fn markdown_table() -> String {
    let mut out = String::from(
        "| flag | TOML key | Python keyword | range | default | meaning |\n|---|---|---|---|---|---|\n",
    );
    for def in &OPTIONS {
        let flag = flag_cell(def);
        let range = match def.kind {
            Kind::Choice(choices) => choices
                .iter()
                .map(|(name, _)| format!("`{name}`"))
                .collect::<Vec<_>>()
                .join(", "),
            _ => def.range.describe(),
        };
        let keys: Vec<String> = def.toml_keys().map(|k| format!("`{k}`")).collect();
        let keys = match keys.is_empty() {
            true => "none".to_string(),
            false => keys.join(" or "),
        };
        out.push_str(&format!(
            "| {flag} | {keys} | `{}` | {range} | {} | {} |\n",
            def.python,
            def.default,
            summary(def).replace('|', "\\|"),
        ));
    }
    out
}
