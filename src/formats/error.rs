use std::fmt;
use std::io;
use std::path::{Path, PathBuf};

/// Why a scene could not be loaded.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SceneError {
    /// A file could not be read.
    #[error("{}: {error}", path.display())]
    Io {
        /// The file, as it was named.
        path: PathBuf,
        /// What the system said (part of the message, so not also a `source`).
        error: io::Error,
    },
    /// A line of a scene file is malformed.
    #[error("{}:{line}: {kind}", path.display())]
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong with the line.
        kind: ParseErrorKind,
    },
    /// An element of a PLY file's body is malformed or cut short.
    #[error("{}: {element} {index}: {kind}", location(path, *line))]
    Element {
        /// The file.
        path: PathBuf,
        /// 1-based line where the element starts, for ascii files.
        line: Option<usize>,
        /// The element's name, such as `face`.
        element: String,
        /// 0-based index of the element among those of its name.
        index: usize,
        /// What is wrong (boxed: it keeps every `Result<_, SceneError>` small).
        kind: Box<ParseErrorKind>,
    },
    /// The file's name names no scene format the renderer reads.
    #[error(
        "{}: not a scene file the renderer reads (supported: {}, each optionally .gz)",
        path.display(),
        crate::formats::SUPPORTED_EXTENSIONS
    )]
    UnknownFormat {
        /// The file, as it was named.
        path: PathBuf,
    },
    /// A glTF file that cannot be read: invalid JSON or GLB, a buffer that is missing
    /// or too short, indices outside their vertices.
    #[error("{}: {message}", path.display())]
    Gltf {
        /// The glTF file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// A file named by a scene file failed to load; `error` carries its own location.
    #[error("{}:{line}: {key}: {error}", path.display())]
    Included {
        /// The scene file that names the failing file.
        path: PathBuf,
        /// 1-based line of the naming key.
        line: usize,
        /// The key, such as `mesh.file`.
        key: String,
        /// Why the named file failed. Not a `source`: the message already includes it,
        /// and `{:#}` would print it twice.
        error: Box<SceneError>,
    },
}

/// `path:line`, or `path` alone when there is no line (binary files).
fn location(path: &std::path::Path, line: Option<usize>) -> String {
    match line {
        Some(line) => format!("{}:{line}", path.display()),
        None => path.display().to_string(),
    }
}

/// What is wrong with a malformed line.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ParseErrorKind {
    /// A token that should be a number is not one.
    #[error("invalid number '{0}'")]
    BadNumber(String),
    /// A number is infinite or NaN.
    #[error("non-finite value '{0}'")]
    NonFinite(String),
    /// A statement has fewer values than it needs.
    #[error("'{statement}' needs {expected} value{}, found {found}", if *expected == 1 { "" } else { "s" })]
    TooFewValues {
        /// The keyword, such as `v`.
        statement: &'static str,
        /// How many it needs.
        expected: usize,
        /// How many the line has.
        found: usize,
    },
    /// A face vertex is not `v`, `v/vt`, `v//vn` or `v/vt/vn`.
    #[error("malformed face vertex '{0}'")]
    BadFaceVertex(String),
    /// A face names index 0, which OBJ does not define.
    #[error("{0} index 0 is invalid (indices start at 1)")]
    ZeroIndex(IndexKind),
    /// A face index points outside the elements defined so far.
    #[error("{kind} index {index} out of range ({defined} {} defined)", kind.counted(*defined))]
    IndexOutOfRange {
        /// Which array.
        kind: IndexKind,
        /// The index as written.
        index: i64,
        /// How many elements existed at that line.
        defined: usize,
    },
    /// A PLY face with fewer than 3 vertices (an OBJ face is skipped with a warning).
    #[error("face has {0} vertices, needs at least 3")]
    TooFewVertices(usize),
    /// An `s` statement whose group is neither `off` nor a whole number.
    #[error("smoothing group '{0}' is not 'off' or a whole number")]
    BadSmoothingGroup(String),
    /// A sphere with a negative radius.
    #[error("sphere radius {0} is negative")]
    NegativeRadius(f32),
    /// A file named by `mtllib` cannot be read.
    #[error("cannot read material library {}: {reason}", shown_path(path))]
    MaterialLibrary {
        /// Where the library was looked for (relative to the OBJ file's folder).
        path: PathBuf,
        /// What the system said.
        reason: String,
    },
    /// The file holds a NUL byte: binary data, or text in UTF-16 rather than UTF-8.
    #[error("not a text file: a NUL byte (binary data, or UTF-16 text)")]
    NotText,
    /// A statement that needs a name has none.
    #[error("'{0}' needs a name")]
    MissingName(&'static str),
    /// A material property before any `newmtl`.
    #[error("'{0}' before any 'newmtl'")]
    PropertyBeforeNewmtl(String),
    /// More elements than the renderer can index with 32 bits.
    #[error("too many {0} (the limit is 4294967295)")]
    TooMany(&'static str),
    /// A TOML document that is not valid TOML.
    #[error("{0}")]
    TomlSyntax(String),
    /// A TOML key with a wrong, unknown or out-of-range value.
    #[error("{key}: {message}")]
    TomlValue {
        /// The dotted key, such as `camera.fov`.
        key: String,
        /// What is wrong with it.
        message: String,
    },
    /// A file that does not start with the PLY magic line.
    #[error("not a PLY file (the first line must be 'ply')")]
    NotPly,
    /// A PLY header line that is not understood.
    #[error("{0}")]
    PlyHeader(String),
    /// A PLY file that ends inside an element.
    #[error("file ends inside the element")]
    Truncated,
    /// An ascii PLY element line with fewer values than its properties need.
    #[error("the line ends before property '{0}'")]
    MissingValue(String),
    /// An ascii PLY element line with more values than its properties (or a wrong
    /// list count).
    #[error("unexpected value '{0}' after the element's last property")]
    ExtraValue(String),
    /// A transform that would turn spheres into ellipsoids.
    #[error("spheres need the same scale on every axis")]
    NonUniformSphereScale,
    /// A texture map option with a value it does not take.
    #[error("'{option}' takes {expected}, found '{value}'")]
    BadOption {
        /// The option, such as `-clamp`.
        option: &'static str,
        /// The value as written.
        value: String,
        /// What it takes.
        expected: &'static str,
    },
    /// A placement or `.npy` file of instances that cannot be used, and why.
    #[error("{0}")]
    Instancing(String),
    /// A PLY list count that is negative.
    #[error("negative list length {0}")]
    NegativeCount(i64),
}

/// A path for a message, cut after [`MAX_SHOWN_PATH`] characters: it comes from a
/// line of the file, which may be megabytes long.
pub(super) fn shown_path(path: &Path) -> String {
    let full = path.display().to_string();
    match full.char_indices().nth(MAX_SHOWN_PATH) {
        Some((cut, _)) => format!("{}...", &full[..cut]),
        None => full,
    }
}

const MAX_SHOWN_PATH: usize = 120;

/// Which array a face index refers to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum IndexKind {
    /// `v` positions.
    Vertex,
    /// `vt` texture coordinates.
    TexCoord,
    /// `vn` normals.
    Normal,
}

impl IndexKind {
    /// The elements' name, singular for a count of 1.
    fn counted(self, count: usize) -> &'static str {
        match (self, count) {
            (IndexKind::Vertex, 1) => "vertex",
            (IndexKind::Vertex, _) => "vertices",
            (IndexKind::TexCoord, 1) => "texture coordinate",
            (IndexKind::TexCoord, _) => "texture coordinates",
            (IndexKind::Normal, 1) => "normal",
            (IndexKind::Normal, _) => "normals",
        }
    }
}

impl fmt::Display for IndexKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            IndexKind::Vertex => "face",
            IndexKind::TexCoord => "texture coordinate",
            IndexKind::Normal => "normal",
        })
    }
}
