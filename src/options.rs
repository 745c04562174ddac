//! What to render: image size, camera and mode.
//!
//! Values come from three places, built-in defaults < scene file < command-line flags.
//! Each place gives a [`PartialOptions`] whose values keep their [`Origin`] and are
//! not range-checked where they are read; [`PartialOptions::or`] merges them and
//! [`PartialOptions::resolve`] checks the result once. So a valid flag replaces a bad
//! value of a scene file, and every error names where its value came from: the flag,
//! or the file, line and key.

use std::fmt;
use std::path::PathBuf;

use crate::math::{Aabb, Float, Vec3, try_unit};
use crate::sampler::MAX_SAMPLES_PER_PIXEL;
use glam::DVec3;

pub mod defs;
pub use defs::{OPTIONS, OptionDef, OptionId};

/// Vertical field of view in degrees of a camera that frames the scene
/// ([`PartialOptions::framed`]) when neither a flag nor the scene file sets one: a
/// model viewer's (three.js's `<model-viewer>` takes 30, Blender's default camera
/// about 40), where [`RenderOptions::default`]'s 90 (SPEC's) would show the model small
/// and distorted.
pub const FRAMED_FOV_DEGREES: Float = 40.0;
/// How far above the horizontal a camera that frames the scene looks down at it, in
/// degrees.
pub const FRAMED_ELEVATION_DEGREES: f64 = 22.0;
/// How far a camera that frames the scene is turned from straight in front of the
/// model towards its +x side (to the viewer's right), in degrees: a figure facing +z
/// is seen three-quarter from the front.
pub const FRAMED_AZIMUTH_DEGREES: f64 = 30.0;
/// The fraction of the image's width or height that the projection of the framed
/// box spans in its limiting dimension: a margin of 4% of the image each side.
pub const FRAMED_FILL: f64 = 0.92;

/// Largest width or height accepted.
pub const MAX_DIMENSION: u32 = 65_536;
/// Largest pixel count accepted (a 16k x 16k image); the linear film alone takes
/// 12 bytes per pixel.
pub const MAX_PIXELS: u64 = 16_384 * 16_384;
/// Largest recursion depth accepted in full mode; the recursion uses the call stack.
pub const MAX_RECURSION_DEPTH: u32 = 64;
/// Largest path length accepted in path mode (a loop, not a recursion).
pub const MAX_PATH_DEPTH: u32 = 1024;
/// Path mode's default path length and samples per pixel (Mitsuba's `max_depth` is
/// unlimited by default; 64 segments end nearly every path by Russian roulette).
pub const PATH_DEFAULTS: (u32, u32) = (64, 64);
/// Full mode's default samples per pixel in a scene it lights with the default rig
/// (a model file without lights: the first picture of a model, as a model viewer
/// shows it with multisampling): four stratified samples smooth its edges and the
/// moire a finely textured or normal-mapped surface makes at one ray per pixel
/// centre, for 1.5 to 3 times the whole process's time (median 2.3x over 39 real
/// model files at 640 x 480, the slowest 0.35 s; a 1.3 MB controller model 0.27
/// against 0.11 s). Scenes with lights of their own keep SPEC's one ray through
/// each pixel centre, and so do renders with extra outputs (`--aovs`), which are
/// data.
pub const RIG_SAMPLES_PER_PIXEL: u32 = 4;
/// Largest exposure accepted, in stops either way.
pub const MAX_EXPOSURE_STOPS: Float = 64.0;

/// What the renderer computes per pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Mode {
    /// Distance to the nearest hit, normalized by the image's largest.
    Depth,
    /// The unit normal at the nearest hit, facing the ray (zero on a miss); shown as
    /// the colour `n / 2 + 1/2`.
    Normal,
    /// Whitted lighting, tone mapped and gamma corrected.
    #[default]
    Full,
    /// Physically based path tracing with area lights ([`crate::integrators::path`]);
    /// shown with an exposure and the sRGB curve.
    Path,
}

impl Mode {
    /// Every mode by its name on the command line and in scene files.
    pub const NAMES: [(&'static str, Mode); 4] = [
        ("full", Mode::Full),
        ("depth", Mode::Depth),
        ("normal", Mode::Normal),
        ("path", Mode::Path),
    ];

    /// The mode's name, as [`Mode::NAMES`] spells it.
    pub fn name(self) -> &'static str {
        Mode::NAMES
            .iter()
            .find(|(_, mode)| *mode == self)
            .map_or("full", |(name, _)| name)
    }
}

impl std::str::FromStr for Mode {
    type Err = String;

    /// A mode by its name in [`Mode::NAMES`], in any letter case.
    fn from_str(name: &str) -> Result<Mode, String> {
        Mode::NAMES
            .iter()
            .find(|(n, _)| n.eq_ignore_ascii_case(name.trim()))
            .map(|&(_, mode)| mode)
            .ok_or_else(|| {
                let names: Vec<&str> = Mode::NAMES.iter().map(|(n, _)| *n).collect();
                format!("unknown mode '{name}' (one of {})", names.join(", "))
            })
    }
}

/// How path mode's PNG maps radiance (after the exposure) to display values: the
/// operators are in [`crate::postprocess`]. Full mode keeps SPEC's tone map whatever
/// this says; depth and normal modes have their own mappings.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ToneMap {
    /// Clamp to 1, then the sRGB curve: the mapping of earlier versions.
    Standard,
    /// Khronos PBR Neutral: base colours under white light come out as they are
    /// (less 0.04) up to 0.8, highlights are compressed towards white keeping their
    /// hue; then the sRGB curve. The default.
    #[default]
    KhronosNeutral,
    /// AgX as Blender and three.js apply it (three.js's `AgXToneMapping`), to sRGB.
    Agx,
    /// Stephen Hill's fit of ACES as three.js's `ACESFilmicToneMapping` (with its
    /// 1/0.6 brightening), then the sRGB curve.
    Aces,
}

impl ToneMap {
    /// Every operator by its name on the command line and in scene files.
    pub const NAMES: [(&'static str, ToneMap); 4] = [
        ("standard", ToneMap::Standard),
        ("khronos-neutral", ToneMap::KhronosNeutral),
        ("agx", ToneMap::Agx),
        ("aces", ToneMap::Aces),
    ];

    /// The operator's name, as [`ToneMap::NAMES`] spells it.
    pub fn name(self) -> &'static str {
        ToneMap::NAMES
            .iter()
            .find(|(_, t)| *t == self)
            .map_or("khronos-neutral", |(name, _)| name)
    }
}

impl std::str::FromStr for ToneMap {
    type Err = String;

    /// An operator by its name in [`ToneMap::NAMES`], in any letter case.
    fn from_str(name: &str) -> Result<ToneMap, String> {
        ToneMap::NAMES
            .iter()
            .find(|(n, _)| n.eq_ignore_ascii_case(name.trim()))
            .map(|&(_, t)| t)
            .ok_or_else(|| {
                let names: Vec<&str> = ToneMap::NAMES.iter().map(|(n, _)| *n).collect();
                format!("unknown tone map '{name}' (one of {})", names.join(", "))
            })
    }
}

/// How the camera projects the scene onto the image.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub enum Projection {
    /// From a point (or a thin lens), with [`RenderOptions::fov_degrees`].
    #[default]
    Perspective,
    /// Parallel rays along the view direction (glTF's orthographic cameras): the
    /// image spans `2 * half_height` scene units vertically, and the width in
    /// proportion to the image's aspect ratio.
    Orthographic {
        /// Half the image's height in scene units (glTF's `ymag`), positive.
        half_height: Float,
    },
    /// From a point, with OpenCV's pinhole intrinsics in pixels instead of
    /// [`RenderOptions::fov_degrees`] (see [`crate::camera::Camera::with_intrinsics`]):
    /// `[camera] intrinsics`, Python's `intrinsics=`.
    Intrinsics {
        /// Horizontal focal length in pixels, positive.
        fx: Float,
        /// Vertical focal length in pixels, positive.
        fy: Float,
        /// Principal point's column, the top-left pixel's centre being 0.
        cx: Float,
        /// Principal point's row.
        cy: Float,
    },
}

/// What camera rays that leave the scene see instead of the environment (which still
/// lights it): `--background`, Python's `background=`, TOML's `environment.background`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Background {
    /// A colour.
    Colour(Vec3),
    /// Nothing: the coverage is written as alpha (RGBA PNG, EXR `A`).
    Transparent,
}

/// Options of one render. Build with [`Default`] and field updates, then
/// [`RenderOptions::validate`]; or from scene files and flags with [`PartialOptions`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderOptions {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Vertical field of view in degrees, strictly between 0 and 180.
    pub fov_degrees: Float,
    /// Camera position.
    pub look_from: Vec3,
    /// Point the camera looks at.
    pub look_to: Vec3,
    /// World up direction (need not be unit length); +y by default.
    pub up: Vec3,
    /// Recursion depth of full mode (1 means primary and shadow rays only); in path
    /// mode the most path segments (Mitsuba's `max_depth`: 1 shows emitters only).
    pub depth: u32,
    /// What to compute.
    pub mode: Mode,
    /// Camera rays per pixel in full mode, averaged in linear space: 1 traces the
    /// pixel centre, more take stratified jittered positions (see
    /// [`crate::sampler`]). Depth and normal modes always take one sample per pixel:
    /// see [`RenderOptions::samples_per_pixel_in_mode`].
    pub samples_per_pixel: u32,
    /// Path mode's exposure in stops: PNG pixels are the radiance times
    /// `2^exposure`, then the sRGB curve. Other modes ignore it.
    pub exposure: Float,
    /// Picks one of many equally valid sets of random numbers; the same seed gives
    /// the same image on any number of threads. 0 gives the images of earlier
    /// versions.
    pub seed: u32,
    /// Whether a scene with no light and no emitter gets the default lighting: in
    /// full mode a light rig at the camera
    /// ([`SceneDescription::add_default_light`](crate::SceneDescription::add_default_light)),
    /// in path mode a studio environment. On by default; `--no-default-light` turns it off.
    pub default_light: bool,
    /// Path mode's tone map of its PNG ([`ToneMap`]); other modes ignore it.
    pub tonemap: ToneMap,
    /// Radius of the camera's thin lens in scene units; 0 (the default) is a pinhole,
    /// everything sharp. Depth and normal modes, and orthographic cameras, ignore it.
    pub aperture_radius: Float,
    /// Distance from the lens to the plane in focus, along the view direction, in
    /// scene units; `None` is the distance from [`RenderOptions::look_from`] to
    /// [`RenderOptions::look_to`]. Only a lens with a radius uses it.
    pub focus_distance: Option<Float>,
    /// Perspective (the default) or orthographic.
    pub projection: Projection,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            width: 640,
            height: 480,
            fov_degrees: 90.0,
            look_from: Vec3::ZERO,
            look_to: Vec3::NEG_Z,
            up: Vec3::Y,
            depth: 4,
            mode: Mode::Full,
            samples_per_pixel: 1,
            exposure: 0.0,
            seed: 0,
            default_light: true,
            tonemap: ToneMap::default(),
            aperture_radius: 0.0,
            focus_distance: None,
            projection: Projection::Perspective,
        }
    }
}

impl RenderOptions {
    /// Checks every value, so that rendering can trust them. The same checks as
    /// [`PartialOptions::resolve`], which also knows where each value came from; here
    /// errors name the flag that sets the value.
    ///
    /// # Errors
    /// The first option out of range, with the allowed range.
    pub fn validate(&self) -> Result<(), OptionsError> {
        Values::from(self)
            .check(&|field| Origin::Flag(field.flag()))
            .map(drop)
    }

    /// The samples per pixel the renderer takes: [`RenderOptions::samples_per_pixel`]
    /// in full mode, 1 in depth and normal modes. An average of distances across a
    /// silhouette is no surface's distance and an average of normals is no unit
    /// normal, so those modes keep exact values (as Blender's depth pass does).
    pub fn samples_per_pixel_in_mode(&self) -> u32 {
        match self.mode {
            Mode::Full | Mode::Path => self.samples_per_pixel,
            Mode::Depth | Mode::Normal => 1,
        }
    }

    /// Whether these options light a scene that is `unlit` (no light, no emitter that
    /// lights it: [`crate::SceneDescription::is_unlit`]) with full mode's default rig:
    /// in full mode with the default light on
    /// ([`crate::SceneDescription::add_default_light`]).
    pub fn lit_by_rig(&self, unlit: bool) -> bool {
        unlit && self.mode == Mode::Full && self.default_light
    }
}

/// Where an option's value came from: what an error names, so that the user knows
/// what to change.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Origin {
    /// The built-in default of [`RenderOptions::default`].
    Default,
    /// A command-line flag, as spelt there: `--width`.
    Flag(&'static str),
    /// A key of a scene file.
    File {
        /// The file, as it was named.
        path: PathBuf,
        /// 1-based line of the value; 0 for a file without lines (glTF).
        line: usize,
        /// The dotted key, such as `camera.width`.
        key: &'static str,
    },
    /// A width or height nobody gave, computed from the other dimension (which came
    /// from the boxed origin) to keep an aspect ratio: see [`PartialOptions::or`].
    Aspect(Box<Origin>),
    /// A camera position nobody gave, placed to frame the whole scene: see
    /// [`PartialOptions::framed`].
    Framed,
}

impl fmt::Display for Origin {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Origin::Default => f.write_str("the default"),
            Origin::Flag(flag) => f.write_str(flag),
            // Line 0: a file without lines (glTF).
            Origin::File { path, line: 0, key } => write!(f, "{}: {key}", path.display()),
            Origin::File { path, line, key } => write!(f, "{}:{line}: {key}", path.display()),
            Origin::Aspect(of) => write!(f, "{of} (keeping the aspect ratio)"),
            Origin::Framed => f.write_str("the camera framing the scene"),
        }
    }
}

/// A value as written, not yet checked, and where it came from.
#[derive(Clone, Debug, PartialEq)]
pub struct Sourced<T> {
    /// The value.
    pub value: T,
    /// Where it came from.
    pub origin: Origin,
}

impl<T> Sourced<T> {
    /// `value` from `origin`.
    pub fn new(value: T, origin: Origin) -> Sourced<T> {
        Sourced { value, origin }
    }
}

/// An option value outside its allowed range, or two values that do not go together.
///
/// Displayed as `FILE:LINE: KEY: MESSAGE` when the value came from a scene file, else
/// as `invalid OPTION: MESSAGE`; a second value from elsewhere is named after it:
/// `invalid --look-from: the camera cannot look at its own position (with
/// scene.toml:4: camera.look_to)`.
#[derive(Debug, Clone, PartialEq)]
pub struct OptionsError {
    /// The flag that sets (or overrides) the value, as the command line spells it:
    /// `--width`, or `--width/--height` for a limit on two flags.
    pub option: &'static str,
    /// Where the value to change came from.
    pub origin: Origin,
    /// For a check of two values from different places, where the other one came
    /// from (boxed: it keeps every `Result<_, OptionsError>` small).
    pub other: Option<Box<Origin>>,
    /// What is wrong, with what is allowed.
    pub message: String,
}

impl fmt::Display for OptionsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.origin {
            Origin::File { .. } => write!(f, "{}: {}", self.origin, self.message)?,
            Origin::Framed => write!(
                f,
                "cannot frame the scene: {}; give --look-from and --look-to",
                self.message
            )?,
            _ => write!(f, "invalid {}: {}", self.option, self.message)?,
        }
        match &self.other {
            Some(other) => write!(f, " (with {other})"),
            None => Ok(()),
        }
    }
}

impl std::error::Error for OptionsError {}

/// The options that are checked, by the flag that sets them.
#[derive(Clone, Copy)]
enum Field {
    Width,
    Height,
    Fov,
    LookFrom,
    LookTo,
    Up,
    Depth,
    Spp,
    Exposure,
    Seed,
    Aperture,
    Focus,
    Projection,
    Intrinsics,
    EnvStrength,
    EnvRotation,
}

impl Field {
    /// The option's definition; `None` for a glTF camera's `ymag`, which only a file
    /// sets.
    fn id(self) -> Option<OptionId> {
        Some(match self {
            Field::Width => OptionId::Width,
            Field::Height => OptionId::Height,
            Field::Fov => OptionId::Fov,
            Field::LookFrom => OptionId::LookFrom,
            Field::LookTo => OptionId::LookTo,
            Field::Up => OptionId::Up,
            Field::Depth => OptionId::Depth,
            Field::Spp => OptionId::Spp,
            Field::Exposure => OptionId::Exposure,
            Field::Seed => OptionId::Seed,
            Field::Aperture => OptionId::ApertureRadius,
            Field::Focus => OptionId::FocusDistance,
            Field::Projection => return None,
            Field::Intrinsics => OptionId::Intrinsics,
            Field::EnvStrength => OptionId::EnvStrength,
            Field::EnvRotation => OptionId::EnvRotation,
        })
    }

    /// The flag that sets the option, as [`OPTIONS`] names it.
    fn flag(self) -> &'static str {
        self.id().map_or("camera.ymag", |id| OptionDef::of(id).flag)
    }

    /// The option's range check: `value` if allowed, else the error naming `origin`.
    fn check(self, value: f64, origin: &Origins) -> Result<(), OptionsError> {
        let range = self
            .id()
            .map_or(defs::Range::Any, |id| OptionDef::of(id).range);
        range
            .check(value)
            .map_err(|message| single_error(self, origin(self), message))
    }

    /// The option's name in prose: `width`.
    fn noun(self) -> &'static str {
        self.flag().trim_start_matches('-')
    }
}

/// Every option before its checks, whole numbers as wide as anyone can write them,
/// so that `-4` is reported as -4.
struct Values {
    width: i64,
    height: i64,
    fov_degrees: Float,
    look_from: Vec3,
    look_to: Vec3,
    up: Vec3,
    depth: i64,
    mode: Mode,
    samples_per_pixel: i64,
    exposure: Float,
    seed: i64,
    default_light: bool,
    tonemap: ToneMap,
    aperture_radius: Float,
    focus_distance: Option<Float>,
    projection: Projection,
    env_strength: Option<Float>,
    env_rotation: Option<Float>,
}

impl From<&RenderOptions> for Values {
    fn from(o: &RenderOptions) -> Values {
        Values {
            width: o.width.into(),
            height: o.height.into(),
            fov_degrees: o.fov_degrees,
            look_from: o.look_from,
            look_to: o.look_to,
            up: o.up,
            depth: o.depth.into(),
            mode: o.mode,
            samples_per_pixel: o.samples_per_pixel.into(),
            exposure: o.exposure,
            seed: o.seed.into(),
            default_light: o.default_light,
            tonemap: o.tonemap,
            aperture_radius: o.aperture_radius,
            focus_distance: o.focus_distance,
            projection: o.projection,
            env_strength: None,
            env_rotation: None,
        }
    }
}

/// Where each checked value came from.
type Origins<'a> = dyn Fn(Field) -> Origin + 'a;

impl Values {
    /// The one check of every option, in a fixed order, stopping at the first error;
    /// `origin` tells where each value came from, for the message.
    fn check(&self, origin: &Origins) -> Result<RenderOptions, OptionsError> {
        let width = dimension(self.width, [Field::Width, Field::Height], origin)?;
        let height = dimension(self.height, [Field::Height, Field::Width], origin)?;
        if u64::from(width) * u64::from(height) > MAX_PIXELS {
            return Err(pair_error(
                [Field::Width, Field::Height],
                "--width/--height",
                origin,
                format!("{width}x{height} has more than {MAX_PIXELS} pixels"),
            ));
        }
        let fov_degrees = self.fov_degrees;
        Field::Fov.check(fov_degrees.into(), origin)?;
        for (field, point) in [
            (Field::LookFrom, self.look_from),
            (Field::LookTo, self.look_to),
        ] {
            if !point.is_finite() {
                return Err(single_error(
                    field,
                    origin(field),
                    "components must be finite".into(),
                ));
            }
        }
        let camera = |message: &str| {
            pair_error(
                [Field::LookFrom, Field::LookTo],
                "--look-from/--look-to",
                origin,
                message.into(),
            )
        };
        if self.look_from == self.look_to {
            return Err(camera("the camera cannot look at its own position"));
        }
        if try_unit(self.look_from - self.look_to).is_none() {
            return Err(camera(
                "the points are too far apart (their distance overflows)",
            ));
        }
        if try_unit(self.up).is_none() {
            return Err(single_error(
                Field::Up,
                origin(Field::Up),
                "components must be finite and not all zero".into(),
            ));
        }
        Field::Exposure.check(self.exposure.into(), origin)?;
        let seed = OptionDef::of(OptionId::Seed)
            .range
            .check_whole(self.seed)
            .and_then(|()| u32::try_from(self.seed).map_err(|e| e.to_string()))
            .map_err(|message| single_error(Field::Seed, origin(Field::Seed), message))?;
        Field::Aperture.check(self.aperture_radius.into(), origin)?;
        if let Some(focus) = self.focus_distance {
            Field::Focus.check(focus.into(), origin)?;
        }
        for (field, value) in [
            (Field::EnvStrength, self.env_strength),
            (Field::EnvRotation, self.env_rotation),
        ] {
            if let Some(value) = value {
                field.check(value.into(), origin)?;
            }
        }
        if let Projection::Orthographic { half_height } = self.projection
            && !(half_height.is_finite() && half_height > 0.0)
        {
            return Err(single_error(
                Field::Projection,
                origin(Field::Projection),
                format!("{half_height} is not a finite half-height greater than 0"),
            ));
        }
        if let Projection::Intrinsics { fx, fy, cx, cy } = self.projection
            && !(fx.is_finite() && fx > 0.0 && fy.is_finite() && fy > 0.0)
                | !(cx.is_finite() && cy.is_finite())
        {
            return Err(single_error(
                Field::Intrinsics,
                origin(Field::Intrinsics),
                format!(
                    "({fx}, {fy}, {cx}, {cy}) are not intrinsics (fx, fy, cx, cy): focal lengths finite and greater than 0, a finite principal point"
                ),
            ));
        }
        let max_depth = match self.mode {
            Mode::Path => MAX_PATH_DEPTH,
            _ => MAX_RECURSION_DEPTH,
        };
        Ok(RenderOptions {
            width,
            height,
            fov_degrees,
            look_from: self.look_from,
            look_to: self.look_to,
            up: self.up,
            depth: whole_number(self.depth, max_depth, Field::Depth, origin)?,
            mode: self.mode,
            samples_per_pixel: whole_number(
                self.samples_per_pixel,
                MAX_SAMPLES_PER_PIXEL,
                Field::Spp,
                origin,
            )?,
            exposure: self.exposure,
            seed,
            default_light: self.default_light,
            tonemap: self.tonemap,
            aperture_radius: self.aperture_radius,
            focus_distance: self.focus_distance,
            projection: self.projection,
        })
    }
}

/// `value` if in `1..=max`.
fn whole_number(value: i64, max: u32, field: Field, origin: &Origins) -> Result<u32, OptionsError> {
    match u32::try_from(value) {
        Ok(v) if (1..=max).contains(&v) => Ok(v),
        _ => Err(single_error(
            field,
            origin(field),
            format!("{value} is not in 1..={max}"),
        )),
    }
}

/// The width or height `field` if in `1..=MAX_DIMENSION`. One computed to keep the
/// aspect ratio is nobody's number: the error names `other`, the dimension it was
/// computed from.
fn dimension(
    value: i64,
    [field, other]: [Field; 2],
    origin: &Origins,
) -> Result<u32, OptionsError> {
    whole_number(value, MAX_DIMENSION, field, origin).map_err(|error| match error.origin {
        Origin::Aspect(of) => {
            single_error(
                other,
                *of,
                format!(
                    "keeping the aspect ratio makes the {} {value}, which is not in 1..={MAX_DIMENSION}; set the {} too",
                    field.noun(),
                    field.noun()
                ),
            )
        }
        _ => error,
    })
}

fn single_error(field: Field, origin: Origin, message: String) -> OptionsError {
    OptionsError {
        option: field.flag(),
        origin,
        other: None,
        message,
    }
}

/// The error of a check on two values. A value computed to keep the aspect ratio is
/// nobody's: the one it follows is named. Otherwise a flag is named before a file's
/// key (the user just typed it, and it overrides the file), and the other value is
/// named too unless it is a default.
fn pair_error(
    [a, b]: [Field; 2],
    option: &'static str,
    origin: &Origins,
    message: String,
) -> OptionsError {
    let (from_a, from_b) = (origin(a), origin(b));
    let aspect_hint = |derived: Field| {
        format!(
            "{message} (the {} keeps the aspect ratio; set it too)",
            derived.noun()
        )
    };
    match (from_a, from_b) {
        (Origin::Aspect(of), _) => single_error(b, *of, aspect_hint(a)),
        (_, Origin::Aspect(of)) => single_error(a, *of, aspect_hint(b)),
        (from_a, from_b)
            if !matches!(from_a, Origin::File { .. }) && !matches!(from_b, Origin::File { .. }) =>
        {
            // Flags or defaults: the pair of flags names both.
            let origin = if from_a == Origin::Default {
                from_b
            } else {
                from_a
            };
            OptionsError {
                option,
                origin,
                other: None,
                message,
            }
        }
        (from_a, from_b) => {
            let (field, blamed, other) =
                if matches!(from_b, Origin::Flag(_)) || from_a == Origin::Default {
                    (b, from_b, from_a)
                } else {
                    (a, from_a, from_b)
                };
            OptionsError {
                option: field.flag(),
                origin: blamed,
                other: (other != Origin::Default).then(|| Box::new(other)),
                message,
            }
        }
    }
}

/// [`RenderOptions`] as one place (the command line, a scene file) gives them: each
/// value optional, not yet checked, and kept with its [`Origin`]. Whole numbers are
/// `i64`, so that a negative or huge value is reported as written. Precedence is
/// explicit: `flags.or(file).resolve()` takes each value from the flags, else from the
/// file, else from [`RenderOptions::default`], then checks them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PartialOptions {
    /// Image width in pixels.
    pub width: Option<Sourced<i64>>,
    /// Image height in pixels.
    pub height: Option<Sourced<i64>>,
    /// Vertical field of view in degrees.
    pub fov_degrees: Option<Sourced<Float>>,
    /// Camera position.
    pub look_from: Option<Sourced<Vec3>>,
    /// Point the camera looks at.
    pub look_to: Option<Sourced<Vec3>>,
    /// World up direction.
    pub up: Option<Sourced<Vec3>>,
    /// Recursion depth of full mode.
    pub depth: Option<Sourced<i64>>,
    /// What to compute.
    pub mode: Option<Sourced<Mode>>,
    /// Camera rays per pixel in full and path modes.
    pub samples_per_pixel: Option<Sourced<i64>>,
    /// Path mode's exposure in stops.
    pub exposure: Option<Sourced<Float>>,
    /// The seed of the random numbers.
    pub seed: Option<Sourced<i64>>,
    /// Whether an unlit scene gets the default lighting.
    pub default_light: Option<Sourced<bool>>,
    /// Path mode's tone map.
    pub tonemap: Option<Sourced<ToneMap>>,
    /// Radius of the thin lens.
    pub aperture_radius: Option<Sourced<Float>>,
    /// Distance to the plane in focus.
    pub focus_distance: Option<Sourced<Float>>,
    /// Perspective or orthographic.
    pub projection: Option<Sourced<Projection>>,
    /// The environment: an image file, or a colour `R,G,B` (not part of
    /// [`RenderOptions`]: it is applied to the scene, as
    /// `formats::environment::EnvironmentOptions` says).
    pub env: Option<Sourced<String>>,
    /// Multiplies the environment's radiance.
    pub env_strength: Option<Sourced<Float>>,
    /// Turns the environment about +Y, in degrees.
    pub env_rotation: Option<Sourced<Float>>,
    /// What camera rays that leave the scene see.
    pub background: Option<Sourced<Background>>,
}

impl PartialOptions {
    /// Each value from `self` if set, else from `fallback`. When `self` sets only one
    /// of width and height, the other keeps the aspect ratio of the image size
    /// `fallback` gives (its own width and height; one of them alone with the other
    /// at the default 640:480; neither, 640x480), rounded to the nearest whole number
    /// and at least 1: `--width 320` on a 640x480 scene file renders 320x240.
    pub fn or(self, fallback: PartialOptions) -> PartialOptions {
        let (width, height) = match (self.width, self.height) {
            (Some(width), None) => {
                let (from_width, from_height) = fallback.image_size();
                let height = keep_aspect(&width, from_width.value, from_height);
                (Some(width), Some(height))
            }
            (None, Some(height)) => {
                let (from_width, from_height) = fallback.image_size();
                let width = keep_aspect(&height, from_height.value, from_width);
                (Some(width), Some(height))
            }
            (width, height) => (width.or(fallback.width), height.or(fallback.height)),
        };
        PartialOptions {
            width,
            height,
            fov_degrees: self.fov_degrees.or(fallback.fov_degrees),
            look_from: self.look_from.or(fallback.look_from),
            look_to: self.look_to.or(fallback.look_to),
            up: self.up.or(fallback.up),
            depth: self.depth.or(fallback.depth),
            mode: self.mode.or(fallback.mode),
            samples_per_pixel: self.samples_per_pixel.or(fallback.samples_per_pixel),
            exposure: self.exposure.or(fallback.exposure),
            seed: self.seed.or(fallback.seed),
            default_light: self.default_light.or(fallback.default_light),
            tonemap: self.tonemap.or(fallback.tonemap),
            aperture_radius: self.aperture_radius.or(fallback.aperture_radius),
            focus_distance: self.focus_distance.or(fallback.focus_distance),
            projection: self.projection.or(fallback.projection),
            env: self.env.or(fallback.env),
            env_strength: self.env_strength.or(fallback.env_strength),
            env_rotation: self.env_rotation.or(fallback.env_rotation),
            background: self.background.or(fallback.background),
        }
    }

    /// These options with a camera that frames `bounds` as a model viewer does, if
    /// neither the camera's position nor its target is set (by a flag or a scene file):
    ///
    /// - it looks from the front and slightly above ([`FRAMED_ELEVATION_DEGREES`]
    ///   above the horizontal, [`FRAMED_AZIMUTH_DEGREES`] to the right), "front"
    ///   being +z as glTF's models face it (+y up), or -y when the world up
    ///   direction is z (Blender's front view of a z-up scene); a scene flat in a plane
    ///   x = c, y = c or z = c (one polygon, a floor), which an angle would show
    ///   foreshortened, is seen face-on along -x, -y or -z;
    /// - unless a flag or the file sets the field of view, it is
    ///   [`FRAMED_FOV_DEGREES`] (vertical), from [`Origin::Framed`];
    /// - from the distance, and aimed at the point, at which the projections of the
    ///   box's 8 corners ([`PartialOptions::framed_by`]: of the scene's points) fit the image (of the size these options give) with
    ///   [`FRAMED_FILL`] of it in the limiting dimension, centred (computed exactly, in
    ///   closed form): the box, and so the scene, is never cut.
    ///
    /// Both points then come from [`Origin::Framed`]. An empty box (an empty scene)
    /// leaves the defaults.
    ///
    /// A camera position given without a target (a lone `--look-from`) looks at the
    /// centre of the box, from [`Origin::Framed`], with the field of view as given
    /// (else [`RenderOptions::default`]'s); a target given alone is kept, with the
    /// default position.
    ///
    /// Call it last, after [`PartialOptions::or`]: the framing depends on the field of
    /// view, the aspect ratio and the world up direction.
    pub fn framed(self, bounds: Aabb) -> PartialOptions {
        let (min, max) = (bounds.min.as_dvec3(), bounds.max.as_dvec3());
        self.framed_by(bounds, |w| (min * w).max(max * w).element_sum())
    }

    /// As [`PartialOptions::framed`], with the scene's own extent: `support(w)` is
    /// the largest `p.w` over the scene's points `p` (its shapes' convex hull; the
    /// box's corners give [`PartialOptions::framed`]), so that the projection of the
    /// scene itself, not of its box, spans [`FRAMED_FILL`] of the limiting dimension,
    /// centred. A long model seen along its length (a VR controller from behind, whose
    /// box's near bottom corner projects far below it) is then centred; the box still
    /// gives the direction of view, and a scene is never cut.
    pub fn framed_by(self, bounds: Aabb, support: impl Fn(DVec3) -> f64) -> PartialOptions {
        self.framed_facing(bounds, support, None)
    }

    /// As [`PartialOptions::framed_by`], for a scene that lies in the plane of normal
    /// `flat` ([`crate::description::Extent::flat_normal`]): seen face-on, from the
    /// side the normal points to if the scene's triangles face it (their winding),
    /// else from the side nearer the usual direction of view, and never from well
    /// below; unless the plane is x, y or z = c (seen along -x, -y or -z as
    /// [`PartialOptions::framed`] says).
    pub fn framed_facing(
        mut self,
        bounds: Aabb,
        support: impl Fn(DVec3) -> f64,
        flat: Option<Flat>,
    ) -> PartialOptions {
        if self.look_to.is_some() || bounds.is_empty() {
            return self;
        }
        if self.look_from.is_some() {
            self.look_to = Some(Sourced::new(bounds.center(), Origin::Framed));
            return self;
        }
        let fov = value_or(&self.fov_degrees, FRAMED_FOV_DEGREES);
        let (width, height) = self.image_size();
        let aspect = width.value.max(1) as f64 / height.value.max(1) as f64;
        // (An invalid field of view gives a nonsense camera here; resolving reports
        // the field of view.)
        let tan_v = (f64::from(fov).to_radians() / 2.0).tan();
        let tan_h = tan_v * aspect;
        let up = value_or(&self.up, RenderOptions::default().up);
        let backward = framing_direction(bounds, up, flat);
        let (right, camera_up) = crate::math::view_basis(backward, up);
        let (backward, right, camera_up) =
            (backward.as_dvec3(), right.as_dvec3(), camera_up.as_dvec3());
        // In f64: the diagonal of a box of 1e30 overflows f32 when squared.
        let (min, max) = (bounds.min.as_dvec3(), bounds.max.as_dvec3());
        // The box's own support where the scene's is not a number (no point at all).
        let support = |w: DVec3| match support(w) {
            s if s.is_finite() => s,
            _ => (min * w).max(max * w).element_sum(),
        };
        let mut size = (max - min).length();
        if size.is_nan() || size <= 0.0 {
            // A single point (or a degenerate box): any distance shows it.
            size = (min.abs().max_element().max(1.0)) * 1e-3;
        }
        // A point p is at most FRAMED_FILL of the half-width right of the image's
        // centre when (p - eye).right <= k (eye - p).backward, k = FRAMED_FILL tan_h:
        // p.(right + k backward) <= eye.(right + k backward); so every corner is when
        // the eye's coordinates (x, y, z) along right, up and backward satisfy
        // x + k z >= support(right + k backward), and likewise on the left, top and
        // bottom. The closest eye has both planes of the limiting dimension touching
        // the box (its projection spans exactly FRAMED_FILL of the image, centred),
        // and the other dimension centred between its planes.
        let (k_h, k_v) = (FRAMED_FILL * tan_h, FRAMED_FILL * tan_v);
        let [right_side, left_side, top, bottom] = [
            right + backward * k_h,
            -right + backward * k_h,
            camera_up + backward * k_v,
            -camera_up + backward * k_v,
        ]
        .map(support);
        let z = ((right_side + left_side) / (2.0 * k_h))
            .max((top + bottom) / (2.0 * k_v))
            // The eye a little outside the box.
            .max(support(backward) + 0.05 * size);
        let (x, y) = ((right_side - left_side) / 2.0, (top - bottom) / 2.0);
        let eye = right * x + camera_up * y + backward * z;
        // The target on the axis of view, level with the box's centre.
        let target = eye - backward * (z - bounds.center().as_dvec3().dot(backward));
        let look_to = target.as_vec3();
        let look_from = eye.as_vec3();
        // A box near the largest f32, or one so small against its distance from the
        // origin that the step rounds away: the defaults stay (and a flag can fix them).
        if !look_from.is_finite() || !look_to.is_finite() || look_from == look_to {
            return self;
        }
        self.look_from = Some(Sourced::new(look_from, Origin::Framed));
        self.look_to = Some(Sourced::new(look_to, Origin::Framed));
        if self.fov_degrees.is_none() {
            self.fov_degrees = Some(Sourced::new(FRAMED_FOV_DEGREES, Origin::Framed));
        }
        self
    }

    /// The options to render with: each value as set, else from
    /// [`RenderOptions::default`] (a width or height alone keeps the default aspect
    /// ratio, as in [`PartialOptions::or`]; path mode's depth and samples per pixel
    /// default to [`PATH_DEFAULTS`]), checked once.
    ///
    /// # Errors
    /// The first value out of range, or the first two values that do not go
    /// together, named by where they came from.
    pub fn resolve(&self) -> Result<RenderOptions, OptionsError> {
        let d = RenderOptions::default();
        let (width, height) = self.image_size();
        let mode = value_or(&self.mode, d.mode);
        let (default_depth, default_spp) = match mode {
            Mode::Path => PATH_DEFAULTS,
            _ => (d.depth, d.samples_per_pixel),
        };
        let values = Values {
            width: width.value,
            height: height.value,
            fov_degrees: value_or(&self.fov_degrees, d.fov_degrees),
            look_from: value_or(&self.look_from, d.look_from),
            look_to: value_or(&self.look_to, d.look_to),
            up: value_or(&self.up, d.up),
            depth: value_or(&self.depth, default_depth.into()),
            mode,
            samples_per_pixel: value_or(&self.samples_per_pixel, default_spp.into()),
            exposure: value_or(&self.exposure, d.exposure),
            seed: value_or(&self.seed, d.seed.into()),
            default_light: value_or(&self.default_light, d.default_light),
            tonemap: value_or(&self.tonemap, d.tonemap),
            aperture_radius: value_or(&self.aperture_radius, d.aperture_radius),
            focus_distance: self.focus_distance.as_ref().map(|f| f.value),
            projection: value_or(&self.projection, d.projection),
            env_strength: self.env_strength.as_ref().map(|s| s.value),
            env_rotation: self.env_rotation.as_ref().map(|r| r.value),
        };
        values.check(&|field| match field {
            Field::Width => width.origin.clone(),
            Field::Height => height.origin.clone(),
            Field::Fov => origin_of(&self.fov_degrees),
            Field::LookFrom => origin_of(&self.look_from),
            Field::LookTo => origin_of(&self.look_to),
            Field::Up => origin_of(&self.up),
            Field::Depth => origin_of(&self.depth),
            Field::Spp => origin_of(&self.samples_per_pixel),
            Field::Exposure => origin_of(&self.exposure),
            Field::Seed => origin_of(&self.seed),
            Field::Aperture => origin_of(&self.aperture_radius),
            Field::Focus => origin_of(&self.focus_distance),
            Field::Projection | Field::Intrinsics => origin_of(&self.projection),
            Field::EnvStrength => origin_of(&self.env_strength),
            Field::EnvRotation => origin_of(&self.env_rotation),
        })
    }

    /// [`PartialOptions::resolve`] for a scene that is `unlit` (no light, no emitter
    /// that lights it: [`crate::SceneDescription::is_unlit`]): one that full mode
    /// lights with the default rig (the default light on) takes
    /// [`RIG_SAMPLES_PER_PIXEL`] samples per pixel unless these options set them, or
    /// unless the render is asked for `extra_outputs` (depth, normals, ids: data,
    /// whose values a dataset wants at the pixel centre, as before, not averaged
    /// across a silhouette).
    ///
    /// # Errors
    /// As [`PartialOptions::resolve`].
    pub fn resolve_for(
        &self,
        unlit: bool,
        extra_outputs: bool,
    ) -> Result<RenderOptions, OptionsError> {
        let mut options = self.resolve()?;
        if options.lit_by_rig(unlit) && !extra_outputs && self.samples_per_pixel.is_none() {
            options.samples_per_pixel = RIG_SAMPLES_PER_PIXEL;
        }
        Ok(options)
    }

    /// The checks of [`PartialOptions::resolve`] that need no scene, for flags checked
    /// before a long load: a camera position given without a target is checked alone,
    /// as [`PartialOptions::framed`] will aim it at the scene's centre.
    ///
    /// # Errors
    /// As [`PartialOptions::resolve`], but for the pair of camera points then.
    pub fn check_before_loading(&self) -> Result<(), OptionsError> {
        let mut options = self.clone();
        if let (Some(from), None) = (&options.look_from, &options.look_to) {
            // Some other point: the scene will give the target.
            let elsewhere = if from.value == Vec3::ZERO {
                Vec3::ONE
            } else {
                Vec3::ZERO
            };
            options.look_to = Some(Sourced::new(elsewhere, Origin::Framed));
        }
        options.resolve().map(drop)
    }

    /// The width and height these options give over the defaults: as set; one alone
    /// with the other at the default aspect ratio; neither, the defaults.
    fn image_size(&self) -> (Sourced<i64>, Sourced<i64>) {
        let d = RenderOptions::default();
        let default = |value: u32| Sourced::new(i64::from(value), Origin::Default);
        let (width, height) = (default(d.width), default(d.height));
        match (&self.width, &self.height) {
            (Some(w), Some(h)) => (w.clone(), h.clone()),
            (Some(w), None) => (w.clone(), keep_aspect(w, width.value, height)),
            (None, Some(h)) => (keep_aspect(h, height.value, width), h.clone()),
            (None, None) => (width, height),
        }
    }
}

/// The dimension that keeps the aspect ratio `before : other` now that the first
/// dimension is `given` instead of `before`: `other * given / before`, rounded to
/// the nearest, at least 1. Without a positive ratio, or with `given` out of range,
/// `other` stays: the checks then report the value that is wrong, not one computed
/// from it.
fn keep_aspect(given: &Sourced<i64>, before: i64, other: Sourced<i64>) -> Sourced<i64> {
    if !(1..=i64::from(MAX_DIMENSION)).contains(&given.value) || before < 1 || other.value < 1 {
        return other;
    }
    // In i128, as `other` may be any i64; half up by integer division.
    let twice = 2 * i128::from(given.value) * i128::from(other.value);
    let rounded = (twice + i128::from(before)) / (2 * i128::from(before));
    Sourced::new(
        i64::try_from(rounded).unwrap_or(i64::MAX).max(1),
        Origin::Aspect(Box::new(given.origin.clone())),
    )
}

/// How far below its plane (the cosine between the view and the world's down
/// direction) the framing camera may look at a flat scene before it looks from the
/// other side ([`PartialOptions::framed_facing`]).
const FLAT_FROM_BELOW: f64 = 0.25;

/// The plane a flat scene lies in
/// ([`Extent::flat_normal`](crate::description::Extent::flat_normal)), for the
/// framing camera to see it face-on ([`PartialOptions::framed_facing`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Flat {
    /// Its unit normal: towards the side the triangles' front faces
    /// (counter-clockwise corners) look to, when most of their area agrees on one.
    pub normal: DVec3,
    /// Whether they do (else the normal may point either way).
    pub faced: bool,
}

/// The unit direction from the centre of `bounds` to the eye of the camera that
/// frames them ([`PartialOptions::framed`]), for the world up direction `up`; along
/// `flat`, the normal of the plane the scene lies in, if given (and the box is not
/// flat in x, y or z).
fn framing_direction(bounds: Aabb, up: Vec3, plane: Option<Flat>) -> Vec3 {
    let extent = bounds.max - bounds.min;
    let flat = |e: Float| e <= 1e-6 * extent.max_element();
    match [flat(extent.x), flat(extent.y), flat(extent.z)] {
        [true, false, false] => return Vec3::X,
        [false, true, false] => return Vec3::Y,
        [false, false, true] => return Vec3::Z,
        _ => {}
    }
    let up = try_unit(up).unwrap_or(Vec3::Y).as_dvec3();
    let front = [DVec3::Z, DVec3::NEG_Y]
        .into_iter()
        .map(|f| f - up * f.dot(up))
        .find(|f| f.length() > 0.1)
        .unwrap_or(DVec3::X)
        .normalize();
    let right = up.cross(front);
    let (elevation, azimuth) = (
        FRAMED_ELEVATION_DEGREES.to_radians(),
        FRAMED_AZIMUTH_DEGREES.to_radians(),
    );
    let direction =
        (front * azimuth.cos() + right * azimuth.sin()) * elevation.cos() + up * elevation.sin();
    let direction = match plane {
        // Face-on: from the side the triangles face (where a texture reads the right
        // way round), else the one the usual view looks at; but not from well below
        // (a face turned down, lit from above in path mode's studio, shows dark).
        Some(Flat { normal, faced }) => {
            let normal = match faced || normal.dot(direction) >= 0.0 {
                true => normal,
                false => -normal,
            };
            match normal.dot(up) < -FLAT_FROM_BELOW {
                true => -normal,
                false => normal,
            }
        }
        None => direction,
    };
    direction.normalize().as_vec3()
}

fn value_or<T: Copy>(value: &Option<Sourced<T>>, default: T) -> T {
    value.as_ref().map_or(default, |v| v.value)
}

fn origin_of<T>(value: &Option<Sourced<T>>) -> Origin {
    value.as_ref().map_or(Origin::Default, |v| v.origin.clone())
}

/// A camera pose as LookAt values: what a camera-to-world matrix says.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pose {
    /// The camera's position.
    pub look_from: Vec3,
    /// A point the camera looks at, straight ahead.
    pub look_to: Vec3,
    /// The camera's up direction in world space.
    pub up: Vec3,
}

/// How far a camera-to-world matrix's rotation may be from orthonormal (per column
/// length and per dot product): matrices written with 6 or 7 digits pass.
const POSE_TOLERANCE: f64 = 1e-4;

/// The LookAt pose of a camera-to-world matrix `m` (rows of four: `m[row][column]`)
/// in OpenGL's and glTF's convention: the camera looks down its -Z axis with +Y up,
/// so the columns are the camera's right, up and backward directions in world space
/// and its position. The camera then looks at `position - backward * s` (with `s =
/// |position| + 1`, so the difference that gives the view direction back is exact
/// to rounding however far the camera is) with up the matrix's up column: a camera
/// whose matrix is exact in floating point (a quarter turn) renders bit for bit as
/// the LookAt camera of the same pose.
///
/// # Errors
/// A message (to follow the argument's name) when a value is not finite, the last
/// row is not `0 0 0 1`, the rotation part is singular, or it is not a rotation (a
/// column's length or two columns' dot product more than 1e-4 from a rotation's, or
/// a mirror image).
pub fn pose_from_matrix(m: [[f64; 4]; 4]) -> Result<Pose, String> {
    for (r, row) in m.iter().enumerate() {
        for (c, v) in row.iter().enumerate() {
            if !v.is_finite() {
                return Err(format!("element [{r}][{c}] is {v}, not a finite number"));
            }
        }
    }
    if m[3] != [0.0, 0.0, 0.0, 1.0] {
        return Err(format!(
            "the last row is {:?}, not [0, 0, 0, 1] (a camera-to-world matrix is a rotation and a translation)",
            m[3]
        ));
    }
    let column = |c: usize| [m[0][c], m[1][c], m[2][c]];
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let [right, up, backward] = [column(0), column(1), column(2)];
    let det = dot(cross(right, up), backward);
    if det.abs() < 1e-12 {
        return Err(format!(
            "the rotation part (the upper-left 3x3) is singular (determinant {det:e})"
        ));
    }
    let names = ["right (column 0)", "up (column 1)", "backward (column 2)"];
    for (axis, name) in [right, up, backward].iter().zip(names) {
        let length = dot(*axis, *axis).sqrt();
        if (length - 1.0).abs() > POSE_TOLERANCE {
            return Err(format!(
                "the {name} axis has length {length}, not 1: the upper-left 3x3 must be a rotation (no scale)"
            ));
        }
    }
    for (a, b) in [(0, 1), (0, 2), (1, 2)] {
        let d = dot(column(a), column(b));
        if d.abs() > POSE_TOLERANCE {
            return Err(format!(
                "columns {a} and {b} are not perpendicular (dot product {d}): the upper-left 3x3 must be a rotation"
            ));
        }
    }
    if det < 0.0 {
        return Err(
            "the upper-left 3x3 is a mirror image (determinant -1), not a rotation".to_string(),
        );
    }
    let vec = |v: [f64; 3]| Vec3::new(v[0] as Float, v[1] as Float, v[2] as Float);
    let position = vec(column(3));
    let reach = position.length() + 1.0;
    Ok(Pose {
        look_from: position,
        look_to: position - vec(backward) * reach,
        up: vec(up),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn from_flag<T>(value: T, name: &'static str) -> Option<Sourced<T>> {
        Some(Sourced::new(value, Origin::Flag(name)))
    }

    fn from_file<T>(value: T, line: usize, key: &'static str) -> Option<Sourced<T>> {
        let path = PathBuf::from("scene.toml");
        Some(Sourced::new(value, Origin::File { path, line, key }))
    }

    fn size(o: &PartialOptions) -> (u32, u32) {
        let o = o.resolve().unwrap_or_else(|e| panic!("{e}"));
        (o.width, o.height)
    }

    fn error(o: &PartialOptions) -> String {
        o.resolve().unwrap_err().to_string()
    }

    #[test]
    fn path_mode_has_its_own_defaults_and_depth_limit() {
        let path = PartialOptions {
            mode: from_flag(Mode::Path, "--mode"),
            ..PartialOptions::default()
        };
        let o = path.resolve().unwrap();
        assert_eq!((o.depth, o.samples_per_pixel), PATH_DEFAULTS);
        let deep = |mode| PartialOptions {
            mode: from_flag(mode, "--mode"),
            depth: from_flag(200, "--depth"),
            ..PartialOptions::default()
        };
        assert_eq!(deep(Mode::Path).resolve().unwrap().depth, 200);
        assert_eq!(
            error(&deep(Mode::Full)),
            "invalid --depth: 200 is not in 1..=64"
        );
        for (stops, ok) in [
            (3.5, true),
            (-64.0, true),
            (65.0, false),
            (Float::NAN, false),
        ] {
            let o = PartialOptions {
                exposure: from_flag(stops, "--exposure"),
                ..path.clone()
            };
            assert_eq!(o.resolve().is_ok(), ok, "{stops}");
        }
        let seed = |value| PartialOptions {
            seed: from_file(value, 9, "render.seed"),
            ..PartialOptions::default()
        };
        assert_eq!(seed(7).resolve().unwrap().seed, 7);
        assert_eq!(
            error(&seed(-1)),
            "scene.toml:9: render.seed: -1 is not in 0..=4294967295"
        );
    }

    #[test]
    fn modes_are_named_in_any_case() {
        for (name, mode) in Mode::NAMES {
            assert_eq!(name.to_uppercase().parse::<Mode>(), Ok(mode));
            assert_eq!(mode.name(), name);
        }
        assert!(
            "fancy"
                .parse::<Mode>()
                .unwrap_err()
                .contains("full, depth, normal, path")
        );
    }

    #[test]
    fn set_values_win_then_fallback_then_defaults() {
        let flags = PartialOptions {
            width: from_flag(10, "--width"),
            height: from_flag(20, "--height"),
            mode: from_flag(Mode::Depth, "--mode"),
            ..PartialOptions::default()
        };
        let file = PartialOptions {
            width: from_file(20, 2, "camera.width"),
            height: from_file(30, 3, "camera.height"),
            up: from_file(Vec3::Z, 4, "camera.up"),
            depth: from_file(7, 6, "render.depth"),
            ..PartialOptions::default()
        };
        let options = flags.or(file).resolve().unwrap();
        assert_eq!((options.width, options.height), (10, 20));
        assert_eq!((options.mode, options.up), (Mode::Depth, Vec3::Z));
        assert_eq!(options.depth, 7);
        assert_eq!(options.fov_degrees, RenderOptions::default().fov_degrees);
        assert_eq!(
            PartialOptions::default().resolve(),
            Ok(RenderOptions::default())
        );
    }

    #[test]
    fn a_valid_flag_replaces_a_bad_file_value() {
        let file = PartialOptions {
            width: from_file(65_536, 2, "camera.width"),
            height: from_file(65_536, 3, "camera.height"),
            fov_degrees: from_file(180.0, 4, "camera.fov"),
            depth: from_file(-1, 6, "render.depth"),
            ..PartialOptions::default()
        };
        assert_eq!(
            error(&file),
            "scene.toml:2: camera.width: 65536x65536 has more than 268435456 pixels \
             (with scene.toml:3: camera.height)"
        );
        let flags = PartialOptions {
            width: from_flag(64, "--width"),
            height: from_flag(48, "--height"),
            fov_degrees: from_flag(60.0, "--fov"),
            depth: from_flag(2, "--depth"),
            ..PartialOptions::default()
        };
        let options = flags.or(file).resolve().unwrap();
        assert_eq!((options.width, options.height), (64, 48));
        assert_eq!((options.fov_degrees, options.depth), (60.0, 2));
    }

    #[test]
    fn errors_name_the_flag_or_the_file_line_and_key() {
        let file_value = PartialOptions {
            depth: from_file(65, 7, "render.depth"),
            ..PartialOptions::default()
        };
        assert_eq!(
            error(&file_value),
            "scene.toml:7: render.depth: 65 is not in 1..=64"
        );
        let err = file_value.resolve().unwrap_err();
        assert_eq!(err.option, "--depth");
        assert!(matches!(err.origin, Origin::File { line: 7, .. }));

        let flag_value = PartialOptions {
            width: from_flag(-5, "--width"),
            ..PartialOptions::default()
        };
        assert_eq!(
            error(&flag_value),
            "invalid --width: -5 is not in 1..=65536"
        );
        for (options, expected) in [
            (
                PartialOptions {
                    fov_degrees: from_file(Float::NAN, 4, "camera.fov"),
                    ..PartialOptions::default()
                },
                "scene.toml:4: camera.fov: NaN is not strictly between 0 and 180",
            ),
            (
                PartialOptions {
                    samples_per_pixel: from_flag(0, "--spp"),
                    ..PartialOptions::default()
                },
                "invalid --spp: 0 is not in 1..=65536",
            ),
            (
                PartialOptions {
                    look_from: from_file(Vec3::NEG_Z, 2, "camera.look_from"),
                    ..PartialOptions::default()
                },
                "scene.toml:2: camera.look_from: the camera cannot look at its own position",
            ),
            (
                PartialOptions {
                    look_from: from_flag(Vec3::ONE, "--look-from"),
                    look_to: from_file(Vec3::ONE, 3, "camera.look_to"),
                    ..PartialOptions::default()
                },
                "invalid --look-from: the camera cannot look at its own position \
                 (with scene.toml:3: camera.look_to)",
            ),
            (
                PartialOptions {
                    look_from: from_file(Vec3::ONE, 2, "camera.look_from"),
                    look_to: from_flag(Vec3::ONE, "--look-to"),
                    ..PartialOptions::default()
                },
                "invalid --look-to: the camera cannot look at its own position \
                 (with scene.toml:2: camera.look_from)",
            ),
            (
                PartialOptions {
                    look_from: from_flag(Vec3::NEG_Z, "--look-from"),
                    ..PartialOptions::default()
                },
                "invalid --look-from/--look-to: the camera cannot look at its own position",
            ),
        ] {
            assert_eq!(error(&options), expected);
        }
    }

    #[test]
    fn one_dimension_keeps_the_aspect_ratio_of_the_size_it_replaces() {
        let file = PartialOptions {
            width: from_file(640, 2, "camera.width"),
            height: from_file(480, 3, "camera.height"),
            ..PartialOptions::default()
        };
        let width = |w| PartialOptions {
            width: from_flag(w, "--width"),
            ..PartialOptions::default()
        };
        let height = |h| PartialOptions {
            height: from_flag(h, "--height"),
            ..PartialOptions::default()
        };
        assert_eq!(size(&width(320).or(file.clone())), (320, 240));
        assert_eq!(size(&height(240).or(PartialOptions::default())), (320, 240));
        // Alone, over the defaults, the same rule.
        assert_eq!(size(&height(240)), (320, 240));
        // Rounded to the nearest, at least 1.
        assert_eq!(size(&width(101).or(file.clone())), (101, 76));
        assert_eq!(size(&width(1).or(file.clone())), (1, 1));
        // A file that sets one dimension has the other at the default ratio.
        let wide = PartialOptions {
            width: from_file(1000, 2, "camera.width"),
            ..PartialOptions::default()
        };
        assert_eq!(size(&wide), (1000, 750));
        assert_eq!(size(&height(300).or(wide)), (400, 300));
        // Replacing a bad size: no ratio to keep, so the file's other value is checked.
        let bad = PartialOptions {
            width: from_file(0, 2, "camera.width"),
            height: from_file(480, 3, "camera.height"),
            ..PartialOptions::default()
        };
        assert_eq!(size(&width(64).or(bad.clone())), (64, 480));
        assert_eq!(
            error(&height(48).or(bad)),
            "scene.toml:2: camera.width: 0 is not in 1..=65536"
        );
    }

    #[test]
    fn a_computed_dimension_out_of_range_names_the_given_one() {
        assert_eq!(
            error(&PartialOptions {
                height: from_flag(65_536, "--height"),
                ..PartialOptions::default()
            }),
            "invalid --height: keeping the aspect ratio makes the width 87381, \
             which is not in 1..=65536; set the width too"
        );
        assert_eq!(
            error(&PartialOptions {
                width: from_flag(65_536, "--width"),
                ..PartialOptions::default()
            }),
            "invalid --width: 65536x49152 has more than 268435456 pixels \
             (the height keeps the aspect ratio; set it too)"
        );
        let huge = PartialOptions {
            width: from_flag(i64::MAX, "--width"),
            ..PartialOptions::default()
        };
        assert_eq!(
            error(&huge),
            format!("invalid --width: {} is not in 1..=65536", i64::MAX)
        );
    }

    #[test]
    fn render_options_name_the_flags() {
        let err = RenderOptions {
            width: 65_536,
            height: 65_536,
            ..RenderOptions::default()
        }
        .validate()
        .unwrap_err();
        assert_eq!(
            err.to_string(),
            "invalid --width/--height: 65536x65536 has more than 268435456 pixels"
        );
        for up in [Vec3::ZERO, Vec3::new(0.0, Float::NAN, 0.0)] {
            let err = RenderOptions {
                up,
                ..RenderOptions::default()
            }
            .validate()
            .unwrap_err();
            assert_eq!(err.option, "--up");
        }
        let err = RenderOptions {
            look_to: Vec3::new(0.0, Float::INFINITY, 0.0),
            ..RenderOptions::default()
        }
        .validate()
        .unwrap_err();
        assert_eq!(
            err.to_string(),
            "invalid --look-to: components must be finite"
        );
    }
}
