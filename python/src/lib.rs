//! Python bindings of the `raytracer` library: the extension module
//! `raytracer._raytracer`, which `python/raytracer/__init__.py` re-exports as the
//! package `raytracer`.
//!
//! A thin layer over the library, doing what the command line does:
//! - scenes are read by [`formats::load`] and built by [`Scene::build`];
//! - the options a Python call gives are [`PartialOptions`] from flags, merged over the
//!   scene file's (`given.or(file).resolve()`), so an argument left out keeps the
//!   file's value and every error has the command line's message;
//! - images are rendered by [`raytracer::render`] and [`raytracer::render_tile`],
//!   post-processed by [`Film::to_image`] and written by the library's atomic writers
//!   ([`Film::write`], [`Image::write_png`]).
//!
//! The interpreter is released (`Python::detach`) while scenes load and images render,
//! post-process or encode. Errors become exceptions: `ValueError` for bad options,
//! [`SceneError`] (an `OSError`) for unreadable or malformed scenes, `OSError` for
//! images that cannot be written. A panic would become pyo3's `PanicException`, never
//! an abort of the interpreter.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use numpy::ndarray::{Array2, Array3, ArrayView3};
use numpy::{AllowTypeChange, IntoPyArray, PyArray1, PyArray3, PyArrayLike3, TypeMustMatch};
use pyo3::create_exception;
use pyo3::exceptions::{PyOSError, PyOverflowError, PyTypeError, PyUserWarning, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyTuple};
use raytracer::film::{Aov, AovPlanes, Outputs};
use raytracer::formats::environment::{EnvironmentNames, EnvironmentOptions};
use raytracer::formats::{self, ParseErrorKind, SceneFormat};
use raytracer::math::{Float, Vec3};
use raytracer::options::defs::{Kind, Range, Value, choice};
use raytracer::options::{
    OPTIONS, OptionDef, OptionId, OptionsError, Origin, PartialOptions, ToneMap,
};
use raytracer::output::{self, UnknownFormatError, WriteError};
use raytracer::postprocess::PostProcessing;
use raytracer::{BvhParams, Film, Image, ImageFormat, Mode, RenderOptions, Scene, Tile, TileError};

mod mesh;
mod rays;
mod run;
use rays::{RAY_ROWS, Reach, blocked_rays, closest_hits, numbers_of, ray_rows};

create_exception!(
    raytracer,
    RaytracerWarning,
    PyUserWarning,
    "What the renderer warns of while reading, building or rendering a scene (a \
     texture it cannot read, degenerate triangles, options that do nothing): the \
     command line's warnings, through Python's ``warnings`` module. Filter them as any \
     warning: ``warnings.simplefilter(\"ignore\", raytracer.RaytracerWarning)``."
);

create_exception!(
    raytracer,
    SceneError,
    PyOSError,
    "A scene file that cannot be read or is malformed (a subclass of OSError). The \
     message is the command line's: it names the file, the line and what is wrong."
);

/// Every failure of the library, turned into a Python exception once the interpreter
/// is attached again.
pub(crate) enum Error {
    Scene(formats::SceneError),
    /// An environment option that cannot be used, its message naming the keyword.
    Environment(String),
    Options(OptionsError),
    Tile(TileError),
    Format(UnknownFormatError),
    Write(WriteError),
}

impl From<Error> for PyErr {
    fn from(error: Error) -> PyErr {
        match error {
            Error::Scene(e) => SceneError::new_err(e.to_string()),
            Error::Options(e) => PyValueError::new_err(python_message(&e.to_string())),
            Error::Environment(message) => PyValueError::new_err(message),
            Error::Tile(e) => PyValueError::new_err(e.to_string()),
            Error::Format(e) => PyValueError::new_err(e.to_string()),
            Error::Write(e) => PyOSError::new_err(e.to_string()),
        }
    }
}

impl From<formats::SceneError> for Error {
    fn from(e: formats::SceneError) -> Error {
        Error::Scene(e)
    }
}

impl From<OptionsError> for Error {
    fn from(e: OptionsError) -> Error {
        Error::Options(e)
    }
}

/// The render options of one Python call, as given, read as [`OPTIONS`] defines each
/// keyword. Their values come from the matching command-line flag ([`Origin::Flag`]),
/// so that messages are the command line's; [`python_message`] then names the
/// keywords instead.
#[derive(Default)]
struct Given<'py> {
    /// The options given; `None` counts as left out.
    options: PartialOptions,
    /// The options given, in order.
    given: Vec<&'static OptionDef>,
    /// `progress=`: not an option of the image, taken by render calls only.
    progress: Option<Bound<'py, PyAny>>,
    /// `aovs=`: the extra outputs, taken by render calls only.
    aovs: Option<Bound<'py, PyAny>>,
    /// `denoise=`: post-processing, as the command line's `--denoise` (not an option
    /// of the image, so not in [`OPTIONS`]), taken by render calls only.
    denoise: Option<Bound<'py, PyAny>>,
}

impl<'py> Given<'py> {
    /// The options among the keyword arguments of a call of `function`: one named
    /// outside [`OPTIONS`] is a `TypeError`, as Python raises for any function;
    /// `None` counts as left out. `progress`, `aovs` and `denoise` are taken when
    /// `with_progress`.
    fn from_keywords(
        function: &str,
        keywords: Option<&Bound<'py, PyDict>>,
        with_progress: bool,
    ) -> PyResult<Self> {
        let mut given = Given::default();
        let mut options = Vec::new();
        for (key, value) in keywords.into_iter().flat_map(|k| k.iter()) {
            let name: String = key.extract()?;
            let slot = match name.as_str() {
                "progress" if with_progress => &mut given.progress,
                "aovs" if with_progress => &mut given.aovs,
                "denoise" if with_progress => &mut given.denoise,
                _ => {
                    let def = OptionDef::by_keyword(&name).ok_or_else(|| {
                        PyTypeError::new_err(format!(
                            "{function}() got an unexpected keyword argument '{name}'"
                        ))
                    })?;
                    if !value.is_none() {
                        options.push((def, value));
                    }
                    continue;
                }
            };
            if !value.is_none() {
                *slot = Some(value);
            }
        }
        given.set_all(options)?;
        Ok(given)
    }

    /// Reads and stores each value as its definition says.
    fn set_all(&mut self, options: Vec<(&'static OptionDef, Bound<'py, PyAny>)>) -> PyResult<()> {
        let named = |id| options.iter().any(|(def, _)| def.id == id);
        if named(OptionId::CameraToWorld)
            && let Some(def) = [OptionId::LookFrom, OptionId::LookTo, OptionId::Up]
                .into_iter()
                .find(|id| named(*id))
        {
            return Err(PyValueError::new_err(format!(
                "give camera_to_world or look_from, look_to and up, not both \
                 (camera_to_world and {} given)",
                OptionDef::of(def).python
            )));
        }
        for (def, value) in options {
            let read = python_value(def, &value).map_err(keyword_error)?;
            def.store(&mut self.options, read, Origin::Flag(def.flag))
                .map_err(|e| {
                    PyValueError::new_err(python_message(&format!("invalid {}: {e}", def.flag)))
                })?;
            self.given.push(def);
        }
        Ok(())
    }

    /// Refuses the scene's options ([`OptionDef::scene`]) in a call on a scene
    /// already built.
    fn refuse_scene_options(&self, function: &str) -> PyResult<()> {
        match self.given.iter().find(|def| def.scene) {
            Some(def) => Err(PyTypeError::new_err(format!(
                "{function}() of a Scene cannot take {}: the environment and background \
                 belong to the scene; give them to raytracer.Scene(...) or \
                 Scene.from_arrays(...), or to raytracer.render(path, ...)",
                def.python
            ))),
            None => Ok(()),
        }
    }

    /// The environment options given (`env`, `env_strength`, `env_rotation`,
    /// `background`).
    fn environment(&self) -> EnvironmentOptions {
        EnvironmentOptions::from_options(&self.options)
    }
}

/// The value of `def` in a Python object, checked for its kind only (ranges are
/// checked once, after merging over the scene file's values). Messages name the
/// command line's flags, for [`keyword_error`] to rename.
fn python_value(def: &OptionDef, value: &Bound<'_, PyAny>) -> PyResult<Value> {
    let flag = def.flag;
    Ok(match def.kind {
        Kind::Whole => Value::Whole(whole_number(value, flag)?),
        Kind::Number => Value::Number(number(value, flag)?),
        Kind::Vector | Kind::Background => Value::Vector(vector(value, flag)?),
        Kind::Choice(choices) => {
            let name = value
                .extract::<String>()
                .map_err(|e| PyTypeError::new_err(format!("{}: {e}", def.python)))?;
            // Tone maps were taken in any letter case from the start (`"ACES"`);
            // modes only as spelt.
            let any_case = def.id == OptionId::ToneMap;
            choice(choices, name.clone())
                .or_else(|e| match any_case {
                    true => choice(choices, name.to_lowercase()),
                    false => Err(e),
                })
                .map_err(|e| PyValueError::new_err(format!("invalid {flag}: {e}")))?
        }
        Kind::SwitchOff => Value::Switch(
            value
                .extract::<bool>()
                .map_err(|e| PyTypeError::new_err(format!("{}: {e}", def.python)))?,
        ),
        Kind::FileOrColour => {
            if let Ok(path) = value.extract::<PathBuf>() {
                return Ok(Value::Text(path.to_string_lossy().into_owned()));
            }
            let colour = vector(value, flag).map_err(|_| {
                PyTypeError::new_err(format!(
                    "{} must be an image file's path or a colour (r, g, b), not {value}",
                    def.python
                ))
            })?;
            Value::Text(format!("{},{},{}", colour.x, colour.y, colour.z))
        }
        Kind::Matrix => Value::Matrix(camera_matrix(value)?),
        Kind::Intrinsics => Value::Four(intrinsics(value)?),
    })
}

impl Given<'_> {
    /// Whether `denoise=True` was given; an error naming the keyword if this build
    /// has no denoiser, before any work, as the command line's `--denoise`.
    fn denoise(&self) -> PyResult<bool> {
        let Some(value) = &self.denoise else {
            return Ok(false);
        };
        let denoise: bool = value.extract().map_err(|_| {
            PyTypeError::new_err(format!("denoise must be True or False, not {value}"))
        })?;
        if denoise && raytracer::postprocess::check_denoiser().is_err() {
            return Err(PyValueError::new_err(
                "denoise=True: these bindings were built without the denoiser: rebuild them \
                 with `maturin build --release --features denoise`, with OIDN_DIR naming Intel \
                 Open Image Denoise (for example the `oidn` folder of PyPI's `pyoidn` wheel)",
            ));
        }
        Ok(denoise)
    }

    /// The extra outputs `aovs=` asks for: `None` when not given (the render returns
    /// the colour image alone), else their list (then a dict).
    fn aov_list(&self) -> PyResult<Option<Vec<Aov>>> {
        let Some(value) = &self.aovs else {
            return Ok(None);
        };
        let names: Vec<String> = if let Ok(one) = value.extract::<String>() {
            vec![one]
        } else {
            value.extract().map_err(|_| {
                PyTypeError::new_err(format!("aovs must be a list of output names, not {value}"))
            })?
        };
        let mut aovs = Vec::new();
        for name in &names {
            let aov: Aov = name.parse().map_err(|_| {
                let known: Vec<&str> = Aov::ALL.iter().map(|a| a.name()).collect();
                PyValueError::new_err(format!(
                    "invalid aovs: unknown output {name:?} (one of {})",
                    known.join(", ")
                ))
            })?;
            if aovs.contains(&aov) {
                return Err(PyValueError::new_err(format!(
                    "invalid aovs: {name:?} is asked for twice"
                )));
            }
            aovs.push(aov);
        }
        Ok(Some(aovs))
    }
}

impl Given<'_> {
    /// The given values, converted but not range-checked: ranges are checked once,
    /// after merging over the scene file's values.
    fn options(&self) -> PartialOptions {
        self.options.clone()
    }
}

/// A 4x4 matrix of numbers (a numpy array or nested sequences).
fn camera_matrix(value: &Bound<'_, PyAny>) -> PyResult<[[f64; 4]; 4]> {
    let rows = numbers_of(value, "camera_to_world", "a 4x4 matrix of numbers")?;
    let rows = rows.as_array();
    if rows.shape() != [4, 4] {
        return Err(PyValueError::new_err(format!(
            "invalid camera_to_world: a 4x4 matrix, not of the shape {}",
            rays::shape_text(rows.shape())
        )));
    }
    // In f64 from the caller's values: float32 would round the rotation.
    let numpy = value.py().import("numpy")?;
    let doubles = numpy.call_method1("asarray", (value, "float64"))?;
    let doubles: Vec<Vec<f64>> = doubles.call_method0("tolist")?.extract()?;
    Ok(std::array::from_fn(|r| {
        std::array::from_fn(|c| doubles[r][c])
    }))
}

/// OpenCV's pinhole intrinsics `(fx, fy, cx, cy)` in pixels.
fn intrinsics(value: &Bound<'_, PyAny>) -> PyResult<[Float; 4]> {
    let numbers = value
        .extract::<Vec<f64>>()
        .map_err(|e| PyTypeError::new_err(format!("intrinsics: {e}")))?;
    match numbers[..] {
        [fx, fy, cx, cy] => Ok([fx as Float, fy as Float, cx as Float, cy as Float]),
        _ => Err(PyValueError::new_err(format!(
            "invalid intrinsics: four numbers (fx, fy, cx, cy), not {}",
            numbers.len()
        ))),
    }
}

/// `error` with [`python_message`]'s names if it is a `ValueError` or `TypeError`.
fn keyword_error(error: PyErr) -> PyErr {
    Python::attach(|py| {
        let message = python_message(&error.value(py).to_string());
        if error.is_instance_of::<PyValueError>(py) {
            PyValueError::new_err(message)
        } else if error.is_instance_of::<PyTypeError>(py) {
            PyTypeError::new_err(message)
        } else {
            error
        }
    })
}

/// A message of the library's, with each command-line flag (`--look-from`) named as
/// the Python keyword that sets it (`look_from`).
fn python_message(message: &str) -> String {
    let mut out = String::with_capacity(message.len());
    let mut rest = message;
    while let Some(at) = rest.find("--") {
        let starts_word = at == 0
            || rest[..at]
                .chars()
                .next_back()
                .is_some_and(|c| matches!(c, ' ' | '/' | '(' | ','));
        out.push_str(&rest[..at]);
        let name_end = rest[at + 2..]
            .find(|c: char| !(c.is_ascii_lowercase() || c == '-'))
            .map_or(rest.len(), |n| at + 2 + n);
        let flag = &rest[at..name_end];
        if starts_word && flag.len() > 2 {
            out.push_str(&match OptionDef::by_flag(flag) {
                Some(def) if def.kind == Kind::SwitchOff => format!("{}=False", def.python),
                Some(def) => def.python.to_string(),
                None => argument(flag),
            });
        } else {
            out.push_str(flag);
        }
        rest = &rest[name_end..];
    }
    out.push_str(rest);
    out
}

/// The Python argument name of a flag: `--look-from` is `look_from`.
fn argument(flag: &str) -> String {
    flag.trim_start_matches('-').replace('-', "_")
}

/// A whole number of any size an `i64` holds; larger ones are a `ValueError` (as the
/// command line's "too many digits"), other types a `TypeError`.
fn whole_number(value: &Bound<'_, PyAny>, flag: &'static str) -> PyResult<i64> {
    value.extract::<i64>().map_err(|e| {
        if e.is_instance_of::<PyOverflowError>(value.py()) {
            PyValueError::new_err(format!("invalid {flag}: {value} has too many digits"))
        } else {
            PyTypeError::new_err(format!("{}: {e}", argument(flag)))
        }
    })
}

/// A number; infinity and NaN too, for the range check to refuse by name.
fn number(value: &Bound<'_, PyAny>, flag: &'static str) -> PyResult<Float> {
    value
        .extract::<f64>()
        .map(|v| v as Float)
        .map_err(|e| PyTypeError::new_err(format!("{}: {e}", argument(flag))))
}

/// Three numbers (any sequence: a tuple, a list, a numpy array).
fn vector(value: &Bound<'_, PyAny>, flag: &'static str) -> PyResult<Vec3> {
    let numbers = value
        .extract::<Vec<f64>>()
        .map_err(|e| PyTypeError::new_err(format!("{}: {e}", argument(flag))))?;
    match numbers[..] {
        [x, y, z] => Ok(Vec3::new(x as Float, y as Float, z as Float)),
        _ => Err(PyValueError::new_err(format!(
            "invalid {flag}: a vector is three numbers (x, y, z), not {}",
            numbers.len()
        ))),
    }
}

/// The mode called `name`. The TOML reader's `render.mode` is the library's one
/// parser of mode names, so the name goes through it: a mode the library gains is
/// known here without a change.
fn parse_mode(name: &str) -> PyResult<Mode> {
    let document = format!("[render]\nmode = {}\n", toml_string(name));
    let invalid = |message: String| PyValueError::new_err(format!("invalid --mode: {message}"));
    match formats::parse_toml(document.as_bytes(), Path::new("--mode")) {
        Ok(loaded) => loaded
            .options
            .mode
            .map(|mode| mode.value)
            .ok_or_else(|| invalid(format!("no mode called {name:?}"))),
        Err(formats::SceneError::Parse {
            kind: ParseErrorKind::TomlValue { message, .. },
            ..
        }) => Err(invalid(message)),
        Err(other) => Err(invalid(other.to_string())),
    }
}

/// The tone map called `name` (as `--tonemap` spells it, in any letter case).
fn parse_tonemap(name: &str) -> PyResult<ToneMap> {
    name.parse()
        .map_err(|message| PyValueError::new_err(format!("invalid --tonemap: {message}")))
}

/// `text` as a TOML basic string, quoted and escaped.
fn toml_string(text: &str) -> String {
    let mut quoted = String::with_capacity(text.len() + 2);
    quoted.push('"');
    for c in text.chars() {
        match c {
            '"' => quoted.push_str("\\\""),
            '\\' => quoted.push_str("\\\\"),
            c if c.is_control() => quoted.push_str(&format!("\\u{:04X}", c as u32)),
            c => quoted.push(c),
        }
    }
    quoted.push('"');
    quoted
}

/// The post-processing of `mode` with `exposure` (stops) and `tonemap` (its name;
/// `None` for the default), both for path mode only, checked as the command line
/// checks `--exposure` and `--tonemap`.
fn post_processing(mode: &str, exposure: Float, tonemap: Option<&str>) -> PyResult<PostProcessing> {
    post_processing_as_flags(mode, exposure, tonemap).map_err(keyword_error)
}

/// [`post_processing`] with messages naming the command line's flags.
fn post_processing_as_flags(
    mode: &str,
    exposure: Float,
    tonemap: Option<&str>,
) -> PyResult<PostProcessing> {
    let mode = parse_mode(mode)?;
    let options = RenderOptions {
        exposure,
        ..RenderOptions::default()
    };
    options.validate().map_err(Error::Options)?;
    let tonemap = tonemap.map(parse_tonemap).transpose()?.unwrap_or_default();
    Ok(PostProcessing {
        mode,
        exposure,
        tonemap,
        least_white_point: 0.0,
    })
}

/// The name of `mode` as the command line and scene files spell it: `full`.
fn mode_name(mode: Mode) -> String {
    format!("{mode:?}").to_lowercase()
}

/// A tile `(x, y, width, height)` in pixels.
fn tile(value: &Bound<'_, PyAny>) -> PyResult<Tile> {
    let numbers = value
        .extract::<Vec<i64>>()
        .map_err(|e| PyTypeError::new_err(format!("tile: {e}")))?;
    let [x, y, width, height] = numbers[..] else {
        return Err(PyValueError::new_err(format!(
            "invalid tile: expected (x, y, width, height), got {} numbers",
            numbers.len()
        )));
    };
    let part = |v: i64| {
        u32::try_from(v).map_err(|_| {
            PyValueError::new_err(format!(
                "invalid tile ({x}, {y}, {width}, {height}): {v} is not in 0..={}",
                u32::MAX
            ))
        })
    };
    Ok(Tile {
        x: part(x)?,
        y: part(y)?,
        width: part(width)?,
        height: part(height)?,
    })
}

/// A scene file read and built, with the options the file gives; or a mesh given as
/// arrays, built.
pub(crate) struct Loaded {
    /// The scene file, as named (none for a mesh given as arrays).
    path: Option<PathBuf>,
    scene: Scene,
    options: PartialOptions,
    /// The box around the shapes, for a camera that frames them.
    bounds: raytracer::math::Aabb,
    /// The shapes' corners, spheres and instance boxes, which that camera fits in
    /// the image as the command line's does.
    extent: raytracer::description::Extent,
    /// Whether the scene has no lights ([`SceneDescription::is_unlit`]): full mode
    /// then lights it with the default rig at each render's camera, as the command
    /// line does.
    unlit: bool,
    /// Copies of `scene` as full mode renders it ([`Loaded::lit_for`]), each tagged
    /// with whether the default rig lights it and lent to one render at a time:
    /// built once per Scene (and once more per render running at the same moment),
    /// not once per render; only the rig's two lights change with the camera.
    lit: Mutex<Vec<(bool, Scene)>>,
    /// The objects' names when the scene's own are not the caller's (the meshes of
    /// `from_arrays` placed by instances).
    names: Option<Vec<String>>,
    /// Triangles the description stores (each instanced mesh once) and places (each
    /// instance's copy counted), meshes stored for instances and instances.
    counts: Counts,
}

/// What a description stores and places ([`Loaded::counts`]), for `Scene.counts`.
#[derive(Clone, Copy, Debug)]
struct Counts {
    triangles: u64,
    placed_triangles: u64,
    meshes: usize,
    instances: usize,
}

/// The scene as full mode renders it for one render ([`Loaded::lit_for`]), handed
/// back to its [`Loaded`] when the render ends.
pub(crate) struct LitScene<'a> {
    scene: Option<Scene>,
    /// Whether the default rig lights it (the pool's tag).
    rig: bool,
    pool: &'a Mutex<Vec<(bool, Scene)>>,
}

impl std::ops::Deref for LitScene<'_> {
    type Target = Scene;
    fn deref(&self) -> &Scene {
        self.scene.as_ref().expect("held until dropped")
    }
}

impl Drop for LitScene<'_> {
    fn drop(&mut self) {
        if let Some(scene) = self.scene.take() {
            lock(self.pool).push((self.rig, scene));
        }
    }
}

/// `mutex` locked, even if a render panicked while holding it: the pool only ever
/// holds whole scenes.
fn lock<T>(mutex: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    mutex
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

impl Loaded {
    /// Reads the scene at `path`, sets the environment options `environment` over
    /// the file's, and builds it. Call detached from the interpreter.
    fn read(
        path: &Path,
        access: &formats::FileAccess,
        environment: &EnvironmentOptions,
    ) -> Result<Loaded, Error> {
        test_gate("RAYTRACER_TEST_GATE_LOAD");
        let mut loaded = formats::load_with(path, access)?;
        environment
            .apply(&mut loaded.description, EnvironmentNames::keywords())
            .map_err(Error::Environment)?;
        Ok(Loaded::build(
            Some(path.to_path_buf()),
            loaded.description,
            loaded.options,
        ))
    }

    /// Builds the scene of `description`, whose file's options are `options`. Call
    /// detached from the interpreter.
    fn build(
        path: Option<PathBuf>,
        description: raytracer::SceneDescription,
        options: PartialOptions,
    ) -> Loaded {
        let counts = Counts {
            triangles: description.unique_triangle_count(),
            placed_triangles: description.instanced_triangle_count(),
            meshes: description.meshes.len(),
            instances: description.instances.len(),
        };
        Loaded {
            path,
            bounds: description.bounds(),
            extent: description.extent(),
            unlit: description.is_unlit(),
            scene: Scene::build(description, &BvhParams::default()),
            options,
            lit: Mutex::new(Vec::new()),
            names: None,
            counts,
        }
    }

    /// The given options over the file's, with the command line's framing camera, for
    /// a render asked for `extra_outputs` or not.
    fn resolve(&self, given: PartialOptions, extra_outputs: bool) -> Result<RenderOptions, Error> {
        Ok(formats::resolve_options(
            given,
            self.options.clone(),
            (self.unlit, extra_outputs),
            || (self.bounds, &self.extent),
        )?)
    }

    /// The scene as full mode renders it for `options`, if that differs from the
    /// scene as built: as the command line does, a scene without lights rendered in
    /// full mode gets the default lighting for this camera
    /// ([`SceneDescription::add_default_light`]), and blended surfaces are layers
    /// ([`Scene::set_blend_in_layers`]). Call detached from the interpreter.
    pub(crate) fn lit_for(&self, options: &RenderOptions) -> Option<LitScene<'_>> {
        if options.mode != raytracer::Mode::Full {
            return None;
        }
        let lit = options.lit_by_rig(self.unlit);
        if !lit && !self.scene.has_blended_materials() {
            return None;
        }
        let spare = {
            let mut pool = lock(&self.lit);
            let found = pool.iter().position(|(tag, _)| *tag == lit);
            found.map(|i| pool.swap_remove(i).1)
        };
        let mut scene = spare.unwrap_or_else(|| self.full_mode_copy(options, lit));
        if lit {
            scene.lights = rig(Vec::new(), options).lights;
        }
        Some(LitScene {
            scene: Some(scene),
            rig: lit,
            pool: &self.lit,
        })
    }

    /// A copy of the scene as full mode renders it: blended surfaces as layers, and,
    /// if `lit`, with the default rig's changes to its materials (the ambient light,
    /// no highlight below `Ns` 1) and its studio reflections, and not unlit: what
    /// [`Scene::build`] makes of the description with the rig added, whose BVH does
    /// not depend on the lights or on those material values. The caller sets the
    /// lights for its camera.
    fn full_mode_copy(&self, options: &RenderOptions, lit: bool) -> Scene {
        let mut scene = self.scene.clone();
        scene.set_blend_in_layers(true);
        if lit {
            let materials = std::mem::take(&mut scene.materials);
            let lit = rig(materials, options);
            scene.materials = lit.materials;
            scene.set_lit_by_rig(lit.lit_by_rig);
            scene.unlit = false;
        }
        scene
    }
}

/// A description of no shapes with `materials`, lit by the default rig for the
/// camera of `options` (`options` in full mode with the default light on):
/// [`SceneDescription::add_default_light`] itself, so that its lights and materials
/// are exactly those of the command line's lit scene.
fn rig(
    materials: Vec<raytracer::Material>,
    options: &RenderOptions,
) -> raytracer::SceneDescription {
    let mut description = raytracer::SceneDescription {
        materials,
        ..Default::default()
    };
    // No shapes, so nothing emits: always unlit.
    description.add_default_light(options);
    debug_assert_eq!(description.lights.len(), 2);
    description
}

/// Test hook: the package's tests must see that a call releases the interpreter, and
/// stop a Dask worker inside a tile, at a known step rather than at a lucky moment.
/// When the environment variable `variable` names a file, the (detached) call writes
/// the marker `<file>.<process id>` and waits until `<file>` exists, for a minute at
/// most. Without the variable it costs one look-up per load, render or ray array.
pub(crate) fn test_gate(variable: &str) {
    let Some(gate) = std::env::var_os(variable) else {
        return;
    };
    let gate = PathBuf::from(gate);
    let mut marker = gate.clone().into_os_string();
    marker.push(format!(".{}", std::process::id()));
    if let Err(e) = std::fs::write(&marker, b"") {
        eprintln!(
            "{variable}: cannot write {}: {e}",
            Path::new(&marker).display()
        );
    }
    let deadline = Instant::now() + Duration::from_secs(60);
    while !gate.exists() && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// The film's values, row by row, three per pixel, in the film's own buffer.
fn film_values(film: Film) -> Vec<f32> {
    vector_floats(film.pixels)
}

/// `values` as their coordinates, three per vector, in the same allocation: no copy.
/// A frame's buffers are fresh pages in a Dask worker (whose nanny sets
/// `MALLOC_TRIM_THRESHOLD_`, which makes glibc map every block above 128 KiB afresh),
/// so a copy there costs a page fault per 4 KiB on top of the copy.
fn vector_floats(values: Vec<Vec3>) -> Vec<f32> {
    const _: () = assert!(size_of::<Vec3>() == 3 * size_of::<f32>());
    const _: () = assert!(align_of::<Vec3>() == align_of::<f32>());
    let mut values = std::mem::ManuallyDrop::new(values);
    let (pointer, length, capacity) = (values.as_mut_ptr(), values.len(), values.capacity());
    // SAFETY: glam's `Vec3` is `#[repr(C)]` three `f32` (size and alignment asserted
    // above), so the buffer holds `3 * length` initialised `f32` and was allocated
    // with the layout of `3 * capacity` of them; `values` is not dropped.
    unsafe { Vec::from_raw_parts(pointer.cast::<f32>(), length * 3, capacity * 3) }
}

/// `values` (from [`film_values`]) as a numpy array of shape `(height, width, 3)`,
/// without a copy.
fn film_array(
    py: Python<'_>,
    width: u32,
    height: u32,
    values: Vec<f32>,
) -> Bound<'_, PyArray3<f32>> {
    Array3::from_shape_vec((height as usize, width as usize, 3), values)
        .expect("three values per pixel")
        .into_pyarray(py)
}

/// The width and height of an image array of shape `(height, width, 3)`.
fn image_size(shape: (usize, usize, usize), what: &str) -> PyResult<(u32, u32)> {
    let (height, width, channels) = shape;
    let bad = || {
        PyValueError::new_err(format!(
            "{what} must have the shape (height, width, 3) with at least one pixel, \
             not ({height}, {width}, {channels})"
        ))
    };
    if channels != 3 || width == 0 || height == 0 {
        return Err(bad());
    }
    Ok((
        u32::try_from(width).map_err(|_| bad())?,
        u32::try_from(height).map_err(|_| bad())?,
    ))
}

/// A linear image array as a film.
fn array_film(linear: ArrayView3<'_, f32>) -> PyResult<Film> {
    let (width, height) = image_size(linear.dim(), "the linear image")?;
    let pixels = linear
        .outer_iter()
        .flat_map(|row| {
            row.outer_iter()
                .map(|p| Vec3::new(p[0], p[1], p[2]))
                .collect::<Vec<_>>()
        })
        .collect();
    Ok(Film {
        width,
        height,
        pixels,
    })
}

/// A scene, read and built once, to render many times (another camera, another size,
/// tiles) without reading it again.
///
/// ``Scene(path)`` reads an OBJ (with its MTL files and textures), PLY, glTF or TOML
/// scene file, any of them optionally gzip-compressed, as ``raytracer render`` does;
/// it raises :class:`SceneError` (an ``OSError``) when the file cannot be read or is
/// malformed. A TOML file's camera and render values are kept: they apply to every
/// render unless an argument replaces them.
///
/// ``env``, ``env_strength``, ``env_rotation`` and ``background`` set path mode's
/// environment and background over the file's, as :func:`raytracer.render` takes them.
/// The scene's warnings are :class:`RaytracerWarning` warnings (and ``warnings``).
///
/// ``Scene(path, confined_to=folder)`` opens no file outside ``folder``, whatever the
/// scene names (an absolute path, ``..``, a link): such a library, mesh or buffer is
/// an error, such a texture a warning, each naming the file and line that named it.
/// The Dask renderer reads shipped scenes so.
#[pyclass(name = "Scene", module = "raytracer", frozen)]
struct PyScene {
    loaded: Arc<Loaded>,
}

#[pymethods]
impl PyScene {
    #[new]
    #[pyo3(signature = (path, *, confined_to=None, env=None, env_strength=None, env_rotation=None, background=None))]
    #[allow(clippy::too_many_arguments)]
    fn new<'py>(
        py: Python<'py>,
        path: PathBuf,
        confined_to: Option<PathBuf>,
        env: Option<Bound<'py, PyAny>>,
        env_strength: Option<Bound<'py, PyAny>>,
        env_rotation: Option<Bound<'py, PyAny>>,
        background: Option<Bound<'py, PyAny>>,
    ) -> PyResult<PyScene> {
        let mut given = Given::default();
        given.set_all(
            [env, env_strength, env_rotation, background]
                .into_iter()
                .zip([
                    OptionId::Env,
                    OptionId::EnvStrength,
                    OptionId::EnvRotation,
                    OptionId::Background,
                ])
                .filter_map(|(value, id)| {
                    Some((OptionDef::of(id), value.filter(|v| !v.is_none())?))
                })
                .collect(),
        )?;
        let environment = given.environment();
        let loaded = py.detach(|| {
            let access = match confined_to {
                Some(folder) => formats::FileAccess::confined_to(&folder).map_err(|error| {
                    Error::Scene(formats::SceneError::Io {
                        path: folder,
                        error,
                    })
                })?,
                None => formats::FileAccess::anywhere(),
            };
            Loaded::read(&path, &access, &environment)
        })?;
        warn(py, &loaded.scene.warnings)?;
        Ok(PyScene {
            loaded: Arc::new(loaded),
        })
    }

    /// A scene of one triangle mesh given as arrays, as a ray-casting library takes
    /// it: ``vertices`` of shape ``(n, 3)`` (numbers) and ``faces`` of shape ``(m,
    /// 3)`` (integers, each a row of ``vertices``), such as a ``trimesh.Trimesh``'s.
    /// Every face has the default material (grey, diffuse); the scene has no lights,
    /// so renders light it as the command line lights a model without any. Face
    /// ``i`` is triangle ``i`` of ``intersect``'s ``"primitive"``; faces of zero area
    /// are skipped with a warning (``warnings``). Raises ``ValueError`` for arrays of
    /// another shape, vertices that are not finite and indices out of range, naming
    /// the row.
    #[staticmethod]
    fn from_mesh(
        py: Python<'_>,
        vertices: &Bound<'_, PyAny>,
        faces: &Bound<'_, PyAny>,
    ) -> PyResult<PyScene> {
        let description = mesh::description(vertices, faces)?;
        let loaded = py.detach(|| Loaded::build(None, description, PartialOptions::default()));
        Ok(PyScene {
            loaded: Arc::new(loaded),
        })
    }

    /// A scene of meshes held as arrays, with materials, lights and an environment as
    /// the TOML scene format gives them (``docs/scene-format.md``), read from no file.
    ///
    /// ``meshes`` is a list of dicts: ``vertices`` ``(n, 3)`` and ``faces`` ``(m, 3)``
    /// (integers, rows of ``vertices``), optional ``normals`` ``(n, 3)`` (shading
    /// normals), ``uvs`` ``(n, 2)`` (texture coordinates, v up), ``colors`` ``(n, 3)`` or
    /// ``(n, 4)`` (vertex colours multiplying the diffuse colour: floats linear 0..1,
    /// ``uint8`` or ``uint16`` scaled to it; alpha ignored), ``material`` (a dict
    /// of the TOML material keys, ``Kd``, ``Ks``, ``Ns``, ``Ke``, ``base_color``,
    /// ``metallic``, ``roughness``, ...; ``map_Kd`` or ``base_color_texture``: the base
    /// colour map, an image file's path or a numpy image, ``uint8`` sRGB or float
    /// linear, ``(h, w, 3)``; default: grey diffuse) and ``transforms`` (``(k, 4, 4)``
    /// or ``(4, 4)``: the mesh placed ``k`` times, each matrix applied to column
    /// vectors; with ``k`` above 1 stored once and placed by instances, and then
    /// every mesh is an instance: see :attr:`counts`). ``lights`` is a list of dicts of the
    /// TOML ``[[light]]`` keys; ``environment`` a dict of the ``[environment]`` keys
    /// (``file`` a path or a numpy image, or ``color``; ``strength``, ``rotation``,
    /// ``background``). Objects are numbered mesh after mesh, copy after copy;
    /// triangles mesh after mesh (a copy's by its mesh's numbering).
    ///
    /// Raises ``ValueError`` naming the argument and its first bad element: arrays of
    /// the wrong shape or dtype, indices out of range, values that are not finite, a
    /// singular transform, an unknown key.
    #[staticmethod]
    #[pyo3(signature = (meshes=None, lights=None, environment=None))]
    fn from_arrays<'py>(
        py: Python<'py>,
        meshes: Option<Bound<'py, PyAny>>,
        lights: Option<Bound<'py, PyAny>>,
        environment: Option<Bound<'py, PyAny>>,
    ) -> PyResult<PyScene> {
        let composed = py.import("raytracer._arrays")?.getattr("compose")?.call1((
            meshes,
            lights,
            environment,
        ))?;
        let text: String = composed.get_item(0)?.extract()?;
        let mut arrays = Vec::new();
        for item in composed.get_item(2)?.try_iter()? {
            let item = item?;
            arrays.push(mesh::ArrayMesh {
                vertices: item.get_item(0)?.extract()?,
                faces: item.get_item(1)?.extract()?,
                normals: item.get_item(2)?.extract()?,
                uvs: item.get_item(3)?.extract()?,
                material: item.get_item(4)?.extract()?,
                texture: item.get_item(5)?.extract()?,
                name: item.get_item(6)?.extract()?,
                transforms: item.get_item(7)?.extract()?,
                colours: item.get_item(8)?.extract()?,
            });
        }
        // Every file the document names is an absolute path: messages name the
        // keyword, `from_arrays:LINE: materials.meshes[0].Kx: ...`, not a folder.
        let document = PathBuf::from("from_arrays");
        let loaded = py
            .detach(|| formats::parse_toml(text.as_bytes(), &document))
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        let (description, names) = mesh::arrays_description(loaded.description, &arrays)?;
        drop(arrays);
        let options = loaded.options;
        let mut loaded = py.detach(|| Loaded::build(None, description, options));
        // The scene names instances by number; the caller named its meshes.
        if loaded.scene.object_names().len() == names.len() {
            loaded.names = Some(names);
        }
        warn(py, &loaded.scene.warnings)?;
        Ok(PyScene {
            loaded: Arc::new(loaded),
        })
    }

    /// A scene of a ``trimesh.Trimesh`` or ``trimesh.Scene`` (``pip install
    /// trimesh``): its meshes with their transforms, vertex normals when the mesh
    /// has them, texture coordinates, vertex colours (``visual.vertex_colors`` of a
    /// ``ColorVisuals`` whose ``kind`` is ``'vertex'``, 8-bit as a PLY file's) and
    /// materials (a ``SimpleMaterial``'s colours, glossiness and image; a
    /// ``PBRMaterial``'s base colour, metallic, roughness, emission and base colour
    /// texture), through :meth:`from_arrays`, without a file.
    #[staticmethod]
    fn from_trimesh<'py>(py: Python<'py>, mesh: Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        py.import("raytracer._arrays")?
            .getattr("from_trimesh")?
            .call1((mesh,))
    }

    /// The names of the objects the ``object_id`` output numbers: ``object_names[i]``
    /// is object ``i``'s (a mesh file's name, a glTF node's, ``meshes[k]`` of
    /// :meth:`from_arrays` or its ``name``, with `` copy j`` per transform); shapes
    /// before the first named object are an unnamed object of their own, numbered
    /// first.
    #[getter]
    fn object_names(&self) -> Vec<String> {
        match &self.loaded.names {
            Some(names) => names.clone(),
            None => self.loaded.scene.object_names().to_vec(),
        }
    }

    /// What the scene stores and what it places, as ``raytracer info`` counts them: a
    /// dict of ``triangles`` (stored: each mesh placed by instances once, whatever
    /// its copies), ``placed_triangles`` (rendered: each copy counted), ``meshes``
    /// (stored once for instances), ``instances`` (their copies) and ``primitives``
    /// (the triangles and spheres the built BVHs hold, degenerate ones left out).
    #[getter]
    fn counts<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let Counts {
            triangles,
            placed_triangles,
            meshes,
            instances,
        } = self.loaded.counts;
        let dict = PyDict::new(py);
        dict.set_item("triangles", triangles)?;
        dict.set_item("placed_triangles", placed_triangles)?;
        dict.set_item("meshes", meshes)?;
        dict.set_item("instances", instances)?;
        dict.set_item("primitives", self.loaded.scene.prim_count())?;
        Ok(dict)
    }

    /// The scene file, as it was named; ``None`` for a scene made by ``from_mesh``.
    #[getter]
    fn path(&self) -> Option<PathBuf> {
        self.loaded.path.clone()
    }

    /// Warnings from reading and building (such as skipped zero-area triangles), as
    /// the command line prints them.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.loaded.scene.warnings.clone()
    }

    /// Renders the scene: the linear image before post-processing, a
    /// :class:`raytracer.Image` (a ``float32`` array of shape ``(height, width, 3)``);
    /// see :func:`raytracer.render`, which takes the same arguments but those of the
    /// environment (``env``, ``env_strength``, ``env_rotation``, ``background``),
    /// which belong to the scene: give them to ``Scene(...)``.
    #[pyo3(signature = (*, tile=None, **options))]
    fn render<'py>(
        &self,
        py: Python<'py>,
        tile: Option<&Bound<'py, PyAny>>,
        options: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let given = Given::from_keywords("render", options, true)?;
        given.refuse_scene_options("render")?;
        self.render_given(py, &given, tile)
    }

    /// The options a render with these arguments uses, checked: each argument given,
    /// else the scene file's value, else the default. A dict with the keys ``width``,
    /// ``height``, ``fov``, ``look_from``, ``look_to``, ``up`` (tuples), ``mode`` (its
    /// name), ``depth``, ``spp``, ``spp_in_mode`` (the samples per pixel the mode
    /// takes: 1 in depth and normal modes), ``exposure``, ``seed``, ``tonemap`` (its
    /// name), ``aperture_radius`` and ``focus_distance`` (the distance in use: the
    /// distance from ``look_from`` to ``look_to`` unless given). Raises
    /// ``ValueError`` as a render would.
    #[pyo3(signature = (**options))]
    fn options<'py>(
        &self,
        py: Python<'py>,
        options: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let given = Given::from_keywords("options", options, false)?;
        given.refuse_scene_options("options")?;
        let options = self.resolve(&given)?;
        let dict = PyDict::new(py);
        dict.set_item("width", options.width)?;
        dict.set_item("height", options.height)?;
        dict.set_item("fov", options.fov_degrees)?;
        let triple = |v: Vec3| (v.x, v.y, v.z);
        dict.set_item("look_from", triple(options.look_from))?;
        dict.set_item("look_to", triple(options.look_to))?;
        dict.set_item("up", triple(options.up))?;
        dict.set_item("mode", mode_name(options.mode))?;
        dict.set_item("depth", options.depth)?;
        dict.set_item("spp", options.samples_per_pixel)?;
        dict.set_item("spp_in_mode", options.samples_per_pixel_in_mode())?;
        dict.set_item("exposure", options.exposure)?;
        dict.set_item("seed", options.seed)?;
        dict.set_item("tonemap", options.tonemap.name())?;
        dict.set_item("aperture_radius", options.aperture_radius)?;
        let focus = options
            .focus_distance
            .unwrap_or_else(|| options.look_from.distance(options.look_to));
        dict.set_item("focus_distance", focus)?;
        Ok(dict)
    }

    /// The camera rays through the pixel centres of a render with these arguments
    /// (the same as :meth:`render` takes, ``tile`` and ``progress`` aside), as a
    /// dict of ``float32`` arrays of shape ``(height, width, 3)``: ``"origins"`` and
    /// unit ``"directions"``, row 0 at the top: what the camera sees at each pixel,
    /// for ray casting of your own (:meth:`intersect`) or to check a camera. A thin
    /// lens's rays are given through its centre.
    #[pyo3(signature = (**options))]
    fn camera_rays<'py>(
        &self,
        py: Python<'py>,
        options: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let given = Given::from_keywords("camera_rays", options, false)?;
        given.refuse_scene_options("camera_rays")?;
        let options = self.resolve(&given)?;
        let (width, height) = (options.width, options.height);
        let (origins, directions) = py.detach(move || {
            let camera = raytracer::Camera::for_options(&options);
            let pixels = width as usize * height as usize;
            let (mut origins, mut directions) = (
                Vec::with_capacity(pixels * 3),
                Vec::with_capacity(pixels * 3),
            );
            for row in 0..height {
                for column in 0..width {
                    let ray = camera.pixel_ray(column, row);
                    origins.extend_from_slice(&ray.origin.to_array());
                    directions.extend_from_slice(&ray.dir.to_array());
                }
            }
            (origins, directions)
        });
        let dict = PyDict::new(py);
        dict.set_item("origins", film_array(py, width, height, origins))?;
        dict.set_item("directions", film_array(py, width, height, directions))?;
        Ok(dict)
    }

    /// The closest hit of every ray: ``origins`` and ``directions`` are arrays (or
    /// lists) of shape ``(n, 3)``, one ray per row; a direction need not be unit
    /// length. Returns a dict of arrays of length ``n``:
    ///
    /// - ``"t"`` (``float32``): the distance from the origin to the hit, along the
    ///   direction made unit length; ``inf`` where the ray misses;
    /// - ``"primitive"`` (``int64``): what the ray hits, ``-1`` where it misses: the
    ///   index of the triangle in the order the file lists them (a polygon of ``k``
    ///   corners is ``k - 2`` consecutive triangles: the fan from its first corner
    ///   if it is convex), then of the spheres a scene lists, numbered after all
    ///   triangles;
    /// - ``"u"``, ``"v"`` (``float32``): the hit's barycentric coordinates on its
    ///   triangle, the weights of its second and third corners (0 on spheres and
    ///   misses): the hit point is ``(1 - u - v) * a + u * b + v * c``.
    ///
    /// Rays pass through what a material cuts out (``map_d``, glTF's alpha mask),
    /// as rendering does. The rays are traced on all cores with the interpreter
    /// released. Raises ``ValueError`` for arrays of another shape, values that are
    /// not finite or a zero direction, naming the row.
    fn intersect<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let (origins, directions) = (
            numbers_of(origins, "origins", RAY_ROWS)?,
            numbers_of(directions, "directions", RAY_ROWS)?,
        );
        let (origins, directions) = ray_rows(&origins, &directions)?;
        let (origins, directions) = (
            origins.as_slice().expect("standard layout"),
            directions.as_slice().expect("standard layout"),
        );
        let scene = &self.loaded.scene;
        let hits = py.detach(|| closest_hits(scene, origins, directions))?;
        let dict = PyDict::new(py);
        dict.set_item("t", hits.t.into_pyarray(py))?;
        dict.set_item("primitive", hits.primitive.into_pyarray(py))?;
        dict.set_item("u", hits.u.into_pyarray(py))?;
        dict.set_item("v", hits.v.into_pyarray(py))?;
        Ok(dict)
    }

    /// Whether anything blocks each ray before the distance ``t_max`` (along the
    /// direction made unit length, as ``intersect``'s ``"t"``): a ``bool`` array of
    /// length ``n``, for shadow, visibility and ambient occlusion queries, which stop
    /// at the first blocker found. It goes through ``Scene::occluded_rays``: in
    /// scenes larger than the last-level cache, runs of incoherent rays are walked
    /// several at a time. ``origins`` and ``directions`` are as for ``intersect``;
    /// ``t_max`` is one number for every ray, an array of ``n``, or ``None`` (no
    /// limit). Raises ``ValueError`` as ``intersect`` does, and for a ``t_max`` that
    /// is NaN or of another length.
    #[pyo3(signature = (origins, directions, t_max=None))]
    fn occluded<'py>(
        &self,
        py: Python<'py>,
        origins: &Bound<'py, PyAny>,
        directions: &Bound<'py, PyAny>,
        t_max: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray1<bool>>> {
        let (origins, directions) = (
            numbers_of(origins, "origins", RAY_ROWS)?,
            numbers_of(directions, "directions", RAY_ROWS)?,
        );
        let (origins, directions) = ray_rows(&origins, &directions)?;
        let n = origins.nrows();
        let reach = Reach::of(t_max, n)?;
        let (origins, directions) = (
            origins.as_slice().expect("standard layout"),
            directions.as_slice().expect("standard layout"),
        );
        let scene = &self.loaded.scene;
        let blocked =
            py.detach(|| blocked_rays(scene, origins, directions, |row| reach.at(row)))?;
        Ok(blocked.into_pyarray(py))
    }

    fn __repr__(&self) -> String {
        let source = match &self.loaded.path {
            Some(path) => format!("{:?}", path.display().to_string()),
            None => "a mesh".to_string(),
        };
        format!(
            "raytracer.Scene({source}: {} primitives, {} lights)",
            self.loaded.scene.prim_count(),
            self.loaded.scene.lights.len()
        )
    }
}

impl PyScene {
    /// The given options merged over the scene file's, checked.
    fn resolve(&self, given: &Given<'_>) -> PyResult<RenderOptions> {
        Ok(self.loaded.resolve(given.options(), given.aovs.is_some())?)
    }

    fn render_given<'py>(
        &self,
        py: Python<'py>,
        given: &Given<'py>,
        tile_value: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let denoise = given.denoise()?;
        let options = self.resolve(given)?;
        let tile = tile_value.map(tile).transpose()?;
        let progress = run::Progress::of(given.progress.as_ref())?;
        let aovs = given.aov_list()?;
        let outputs = render_outputs(
            py,
            Arc::clone(&self.loaded),
            options,
            tile,
            (aovs.as_deref().unwrap_or_default(), denoise),
            &progress,
        )?;
        result_of(py, outputs, aovs.is_some(), &options)
    }
}

/// [`run::render`] with the outputs `aovs`, denoised if `denoise` (path mode's
/// colour, guided by its albedo and normal, rendered in the same pass and dropped
/// unless asked for, as the command line's `--denoise`; other modes are returned as
/// rendered, with a warning).
fn render_outputs(
    py: Python<'_>,
    loaded: Arc<Loaded>,
    options: RenderOptions,
    tile: Option<Tile>,
    (aovs, denoise): (&[Aov], bool),
    progress: &run::Progress<'_>,
) -> PyResult<Outputs> {
    let denoising = denoise && options.mode == Mode::Path;
    if denoise && !denoising {
        let mode = mode_name(options.mode);
        warn(
            py,
            &[format!(
                "denoise applies to path mode only; {mode} mode is returned as rendered"
            )],
        )?;
    }
    let mut rendered = aovs.to_vec();
    for guide in [Aov::Albedo, Aov::Normal] {
        if denoising && !rendered.contains(&guide) {
            rendered.push(guide);
        }
    }
    let outputs = run::render(py, loaded, options, tile, rendered, progress)?;
    if !denoising {
        return Ok(outputs);
    }
    let Outputs {
        film,
        aovs: mut planes,
    } = outputs;
    let film = py
        .detach(|| film.denoised(&planes))
        .map_err(|e| PyValueError::new_err(format!("denoise=True: {e}")))?;
    if !aovs.contains(&Aov::Albedo) {
        planes.albedo = None;
    }
    if !aovs.contains(&Aov::Normal) {
        planes.normal = None;
    }
    Ok(Outputs { film, aovs: planes })
}

/// What a render call returns: the colour image alone ([`image_of`]), or with `aovs`
/// asked for, a dict of it (`"color"`) and each output as a numpy array: `depth` and
/// `alpha` `(height, width)` `float32`, `normal` and `albedo` `(height, width, 3)`
/// `float32`, `object_id` and `material_id` `(height, width)` `int32`.
fn result_of<'py>(
    py: Python<'py>,
    outputs: Outputs,
    as_dict: bool,
    options: &RenderOptions,
) -> PyResult<Bound<'py, PyAny>> {
    let Outputs { film, aovs } = outputs;
    let (width, height) = (film.width as usize, film.height as usize);
    let image = image_of(py, film, options)?;
    if !as_dict {
        return Ok(image);
    }
    let dict = PyDict::new(py);
    dict.set_item("color", image)?;
    let plane = |values: Vec<f32>| {
        Array2::from_shape_vec((height, width), values)
            .expect("one value per pixel")
            .into_pyarray(py)
    };
    let ids = |values: Vec<i32>| {
        Array2::from_shape_vec((height, width), values)
            .expect("one value per pixel")
            .into_pyarray(py)
    };
    let vectors =
        |values: Vec<Vec3>| film_array(py, width as u32, height as u32, vector_floats(values));
    let AovPlanes {
        depth,
        normal,
        albedo,
        alpha,
        object_id,
        material_id,
    } = aovs;
    if let Some(v) = depth {
        dict.set_item("depth", plane(v))?;
    }
    if let Some(v) = normal {
        dict.set_item("normal", vectors(v))?;
    }
    if let Some(v) = albedo {
        dict.set_item("albedo", vectors(v))?;
    }
    if let Some(v) = alpha {
        dict.set_item("alpha", plane(v))?;
    }
    if let Some(v) = object_id {
        dict.set_item("object_id", ids(v))?;
    }
    if let Some(v) = material_id {
        dict.set_item("material_id", ids(v))?;
    }
    Ok(dict.into_any())
}

/// A film as the package's image: a `float32` numpy array of shape `(height, width,
/// 3)` (the class `raytracer.Image`, which shows itself in Jupyter as the PNG would
/// show it, post-processed for `options`' mode, exposure and tone map).
fn image_of<'py>(
    py: Python<'py>,
    film: Film,
    options: &RenderOptions,
) -> PyResult<Bound<'py, PyAny>> {
    let (width, height) = (film.width, film.height);
    let values = film_values(film);
    let array = film_array(py, width, height, values);
    py.import("raytracer._image")?
        .getattr("Image")?
        .call_method1(
            "_wrap",
            (
                array,
                mode_name(options.mode),
                options.exposure,
                options.tonemap.name(),
            ),
        )
}

/// Each of `messages` as a [`RaytracerWarning`], through Python's `warnings` module
/// (which may turn one into an exception: then it is raised).
fn warn(py: Python<'_>, messages: &[String]) -> PyResult<()> {
    let category = py.get_type::<RaytracerWarning>();
    for message in messages {
        let text = std::ffi::CString::new(message.replace('\0', " ")).expect("no NUL left");
        PyErr::warn(py, category.as_any(), &text, 1)?;
    }
    Ok(())
}

/// Renders a scene file and returns the linear image before post-processing (what
/// ``raytracer render`` writes to an ``.exr`` file): a :class:`raytracer.Image`, a
/// ``float32`` numpy array of shape ``(height, width, 3)``, row 0 at the top, which
/// Jupyter shows as the PNG would look.
///
/// ``scene`` is a path (``str`` or ``os.PathLike``) to an OBJ, PLY, glTF 2.0
/// (``.gltf``, ``.glb``) or TOML scene file (any of them gzip-compressed), or a
/// :class:`Scene` already read. The other arguments are the command line's
/// flags: ``width``, ``height`` (pixels), ``fov`` (vertical, degrees), ``look_from``,
/// ``look_to``, ``up`` (three numbers each), ``camera_to_world`` (a 4x4 pose matrix in
/// OpenGL's convention, the camera looking down its -Z with +Y up, instead of
/// ``look_from``, ``look_to`` and ``up``), ``intrinsics`` (``(fx, fy, cx, cy)`` in
/// pixels, OpenCV's pinhole model with the top-left pixel's centre at (0, 0), instead
/// of ``fov``), ``mode`` (``"full"``, ``"depth"``,
/// ``"normal"``, ``"path"``), ``depth`` (recursion depth), ``spp`` (samples per
/// pixel), ``exposure`` (path mode's, in stops: used by post-processing only),
/// ``seed`` (of the random numbers), ``tonemap`` (path mode's: ``"standard"``,
/// ``"khronos-neutral"``, ``"agx"``, ``"aces"``; used by post-processing only),
/// ``aperture_radius`` and ``focus_distance`` (the thin lens, scene units),
/// ``default_light`` (``False``: a scene without lights stays unlit, as
/// ``--no-default-light``), ``env`` (path mode's environment: an image file's path or
/// a colour ``(r, g, b)``), ``env_strength``, ``env_rotation`` (degrees about +Y) and
/// ``background`` (``(r, g, b)`` seen instead of the environment). Each one
/// left out (``None``) takes the TOML scene file's value (or a glTF file's camera),
/// else the default: 640x480, fov 90, a camera that frames the scene as a model viewer
/// does (from the front and above, fov 40, as close as lets the corners of its bounds
/// fill 92% of the image, centred) when neither ``look_from`` nor ``look_to`` is set,
/// ``look_from`` alone looking at the centre of the bounds, otherwise from (0, 0, 0); up (0, 1, 0), full mode, depth 4 and 1 sample per
/// pixel (4 under the default light rig unless ``aovs`` are asked for; 64 and 64 in
/// path mode), exposure 0, seed 0, tone map khronos-neutral, a
/// pinhole (aperture radius 0; the focus at ``look_to``, 1 unit ahead with
/// ``camera_to_world``), the default light on, no environment (path mode lights an
/// unlit scene with its studio), strength 1, rotation 0; a width or height alone
/// keeps the aspect ratio.
/// ``tile=(x, y, w, h)`` returns only those pixels, shape ``(h, w, 3)``, bit-identical
/// to the same pixels of the whole image. ``progress`` is ``None`` (the default: no
/// report), ``True`` (a tqdm bar; ``pip install tqdm``) or a callable taking ``(done,
/// total)`` in rows, called from the calling thread; an exception it raises stops the
/// render and is raised. ``denoise=True`` removes path mode's Monte Carlo noise with
/// Intel Open Image Denoise, guided by the albedo and normal rendered in the same pass,
/// as ``--denoise`` does (other modes are returned as rendered, with a warning); it
/// needs bindings built with ``--features denoise``, else it is a ``ValueError``
/// (default ``False``).
///
/// Raises ``ValueError`` for a bad option (naming the keyword) and :class:`SceneError`
/// (an ``OSError``) for a scene file that cannot be read or is malformed, with the
/// command line's message. The scene's warnings are :class:`RaytracerWarning` warnings.
/// The interpreter is released while the scene loads and renders; Ctrl-C raises
/// ``KeyboardInterrupt`` within a fraction of a second and stops the render.
#[pyfunction]
#[pyo3(signature = (scene, *, tile=None, **options))]
fn render<'py>(
    py: Python<'py>,
    scene: &Bound<'py, PyAny>,
    tile: Option<&Bound<'py, PyAny>>,
    options: Option<&Bound<'py, PyDict>>,
) -> PyResult<Bound<'py, PyAny>> {
    let given = Given::from_keywords("render", options, true)?;
    let denoise = given.denoise()?;
    if let Ok(scene) = scene.cast::<PyScene>() {
        given.refuse_scene_options("render")?;
        return scene.get().render_given(py, &given, tile);
    }
    let path: PathBuf = scene.extract()?;
    let flags = given.options();
    let environment = given.environment();
    let tile = tile.map(self::tile).transpose()?;
    let progress = run::Progress::of(given.progress.as_ref())?;
    let aovs = given.aov_list()?;
    let extra_outputs = aovs.is_some();
    let (loaded, options) = py.detach(move || {
        // As the command line: OBJ and PLY files set no options, so the arguments are
        // checked before a long load; a TOML file's values are merged first.
        if !matches!(
            SceneFormat::require(&path)?,
            SceneFormat::Toml | SceneFormat::Gltf
        ) {
            flags.check_before_loading()?;
        }
        let loaded = Loaded::read(&path, &formats::FileAccess::anywhere(), &environment)?;
        let options = loaded.resolve(flags, extra_outputs)?;
        Ok::<_, Error>((loaded, options))
    })?;
    warn(py, &loaded.scene.warnings)?;
    let wanted = (aovs.as_deref().unwrap_or_default(), denoise);
    let outputs = render_outputs(py, Arc::new(loaded), options, tile, wanted, &progress)?;
    result_of(py, outputs, aovs.is_some(), &options)
}

/// Post-processes a linear image (a ``float32`` array of shape ``(height, width, 3)``)
/// for display and encodes it as the bytes of a PNG file, as :meth:`Image._repr_png_`
/// shows it in Jupyter.
#[pyfunction]
#[pyo3(signature = (linear, mode="full", exposure=0.0, tonemap=None))]
fn _png<'py>(
    py: Python<'py>,
    linear: PyArrayLike3<'py, f32, AllowTypeChange>,
    mode: &str,
    exposure: Float,
    tonemap: Option<&str>,
) -> PyResult<Bound<'py, PyBytes>> {
    let post = post_processing(mode, exposure, tonemap)?;
    let film = array_film(linear.as_array())?;
    let bytes = py
        .detach(move || film.to_image(post).encode_png())
        .map_err(|e| PyOSError::new_err(e.to_string()))?;
    Ok(PyBytes::new(py, &bytes))
}

/// Post-processes a linear image for display, exactly as ``raytracer render`` does
/// before writing a PNG: full mode tone maps by the image-wide brightest channel, then
/// applies gamma 2.2; depth mode divides by the farthest distance (misses white);
/// normal mode maps ``n`` to ``n / 2 + 1/2`` (misses black); path mode multiplies by
/// ``2 ** exposure`` and applies the tone map ``tonemap`` (``None``: the default,
/// ``"khronos-neutral"``; ``"standard"`` clamps and applies the sRGB curve; also
/// ``"agx"`` and ``"aces"``; other modes ignore it). Returns a ``uint8`` array of shape
/// ``(height, width, 3)``.
///
/// ``linear`` is an array of shape ``(height, width, 3)``, converted to ``float32``.
/// The maxima are image-wide: merge tiles in linear space first, then post-process.
#[pyfunction]
#[pyo3(signature = (linear, mode="full", exposure=0.0, tonemap=None))]
fn postprocess<'py>(
    py: Python<'py>,
    linear: PyArrayLike3<'py, f32, AllowTypeChange>,
    mode: &str,
    exposure: Float,
    tonemap: Option<&str>,
) -> PyResult<Bound<'py, PyArray3<u8>>> {
    let post = post_processing(mode, exposure, tonemap)?;
    let film = array_film(linear.as_array())?;
    let image = py.detach(move || film.to_image(post));
    Ok(
        Array3::from_shape_vec((image.height as usize, image.width as usize, 3), image.rgb)
            .expect("three bytes per pixel")
            .into_pyarray(py),
    )
}

/// Writes a linear image as ``raytracer render`` does: ``.png`` post-processed for
/// ``mode``, ``exposure`` and ``tonemap`` (as :func:`postprocess`), ``.exr`` the linear values as 32-bit floats
/// (depth mode: the single channel ``Z``). The extension, in any letter case, picks
/// the format; any other is a ``ValueError``.
///
/// Atomic: the image goes to a temporary file in the same folder, renamed over
/// ``path`` once complete, so ``path`` holds either the previous file or the whole new
/// image. Raises ``OSError`` when the file cannot be written.
#[pyfunction]
#[pyo3(signature = (linear, path, mode="full", exposure=0.0, tonemap=None))]
fn write_image(
    py: Python<'_>,
    linear: PyArrayLike3<'_, f32, AllowTypeChange>,
    path: PathBuf,
    mode: &str,
    exposure: Float,
    tonemap: Option<&str>,
) -> PyResult<()> {
    let post = post_processing(mode, exposure, tonemap)?;
    let format = ImageFormat::from_path(&path).map_err(Error::Format)?;
    let film = array_film(linear.as_array())?;
    py.detach(move || film.write(post, format, &path))
        .map_err(Error::Write)?;
    Ok(())
}

/// Writes an 8-bit RGB image (``uint8``, shape ``(height, width, 3)``, as
/// :func:`postprocess` returns) as a PNG file, atomically like :func:`write_image`.
#[pyfunction]
fn write_png(
    py: Python<'_>,
    rgb: PyArrayLike3<'_, u8, TypeMustMatch>,
    path: PathBuf,
) -> PyResult<()> {
    let view = rgb.as_array();
    let (width, height) = image_size(view.dim(), "the RGB image")?;
    let image = Image {
        width,
        height,
        rgb: view.iter().copied().collect(),
    };
    py.detach(move || image.write_png(&path))
        .map_err(Error::Write)?;
    Ok(())
}

/// Checks, before any work, that an image can be written to ``path``, as
/// ``raytracer render`` does: the extension names a format (``ValueError`` if not)
/// and the folder takes new files (``OSError`` if not). Returns the format,
/// ``"png"`` or ``"exr"``.
#[pyfunction]
fn check_output(path: PathBuf) -> PyResult<&'static str> {
    let format = ImageFormat::from_path(&path).map_err(Error::Format)?;
    output::check_output(&path).map_err(Error::Write)?;
    Ok(match format {
        ImageFormat::Png => "png",
        ImageFormat::Exr => "exr",
    })
}

/// The files a load of the scene file at ``path`` asks for, for the Dask renderer: a
/// dict with ``asked`` (every file the readers tried, in order: the scene file, MTL
/// libraries, meshes, textures, glTF buffers and images, missing ones too, as
/// absolute paths), ``refused`` (those outside the scene's folder, when
/// ``confined``), ``error`` (the load's message, or ``None``) and ``warnings``.
/// With ``confined``, files outside the scene's folder are not opened.
#[pyfunction]
fn _scene_files(py: Python<'_>, path: PathBuf, confined: bool) -> PyResult<Bound<'_, PyDict>> {
    let (asked, refused, error, warnings) = py.detach(|| {
        let access = if confined {
            let folder = std::path::absolute(&path)?
                .parent()
                .map(Path::to_path_buf)
                .unwrap_or_default();
            formats::FileAccess::confined_to(&folder)?
        } else {
            formats::FileAccess::anywhere()
        };
        let (error, warnings) = match formats::load_with(&path, &access) {
            Ok(loaded) => (None, loaded.description.warnings),
            Err(e) => (Some(e.to_string()), Vec::new()),
        };
        Ok::<_, std::io::Error>((access.asked(), access.refused(), error, warnings))
    })?;
    let dict = PyDict::new(py);
    dict.set_item("asked", asked)?;
    dict.set_item("refused", refused)?;
    dict.set_item("error", error)?;
    dict.set_item("warnings", warnings)?;
    Ok(dict)
}

/// Whether this process has renamed a complete image over ``path`` (as given to the
/// writer): what an interrupt handler asks, under the lock every final rename takes,
/// to say truly whether the output holds the new image.
#[pyfunction]
fn _committed(path: PathBuf) -> bool {
    output::lock_commits().contains(&path)
}

/// The extension module `raytracer._raytracer`.
/// Every render option as `raytracer::options::OPTIONS` defines it, for the package's
/// tests: a list of dicts with ``python``, ``flag`` (``None`` without one), ``toml``
/// (the dotted key, or ``None``), ``kind``, ``range`` (a tuple: its kind and bounds,
/// or ``None``), ``choices``, ``example`` (as the command line spells it) and
/// ``scene`` (whether it belongs to the scene).
#[pyfunction]
fn _option_table(py: Python<'_>) -> PyResult<Vec<Bound<'_, PyDict>>> {
    OPTIONS
        .iter()
        .map(|def| {
            let dict = PyDict::new(py);
            dict.set_item("python", def.python)?;
            dict.set_item("flag", def.cli.then_some(def.flag))?;
            dict.set_item("toml", def.toml)?;
            let kind = match def.kind {
                Kind::Whole => "whole",
                Kind::Number => "number",
                Kind::Vector => "vector",
                Kind::Choice(_) => "choice",
                Kind::SwitchOff => "switch_off",
                Kind::FileOrColour => "file_or_colour",
                Kind::Background => "background",
                Kind::Matrix => "matrix",
                Kind::Intrinsics => "intrinsics",
            };
            dict.set_item("kind", kind)?;
            let range = match def.range {
                Range::Any => None,
                Range::Whole(min, max) => Some(("whole", min as f64, max as f64)),
                Range::Open(low, high) => Some(("open", low.into(), high.into())),
                Range::Within(bound, _) => Some(("within", (-bound).into(), bound.into())),
                Range::NotNegative(..) => Some(("not_negative", 0.0, f64::INFINITY)),
                Range::Positive(_) => Some(("positive", 0.0, f64::INFINITY)),
                Range::Finite => Some(("finite", f64::NEG_INFINITY, f64::INFINITY)),
            };
            dict.set_item("range", range)?;
            dict.set_item("choices", def.choices())?;
            dict.set_item("example", def.example)?;
            dict.set_item("scene", def.scene)?;
            Ok(dict)
        })
        .collect()
}

#[pymodule]
fn _raytracer(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("SceneError", m.py().get_type::<SceneError>())?;
    m.add("RaytracerWarning", m.py().get_type::<RaytracerWarning>())?;
    m.add_class::<PyScene>()?;
    m.add_function(wrap_pyfunction!(render, m)?)?;
    m.add_function(wrap_pyfunction!(postprocess, m)?)?;
    m.add_function(wrap_pyfunction!(write_image, m)?)?;
    m.add_function(wrap_pyfunction!(write_png, m)?)?;
    m.add_function(wrap_pyfunction!(check_output, m)?)?;
    m.add_function(wrap_pyfunction!(_committed, m)?)?;
    m.add_function(wrap_pyfunction!(_png, m)?)?;
    m.add_function(wrap_pyfunction!(_scene_files, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add(
        "OPTIONS",
        PyTuple::new(m.py(), OPTIONS.iter().map(|def| def.python))?,
    )?;
    m.add_function(wrap_pyfunction!(_option_table, m)?)?;
    Ok(())
}
